"""Finding candidate hits (the paper's segments) and curating them: the segments rule's code.

A segment runs from the ball crossing the net towards a player to that player's strike (the incoming
part, with the hitter's pre-hit frames) and on through the post-hit flight, until the ball crosses the
strike line on the opponent's side, the next hit, or the flight ends. Every candidate keeps its
decision: 'kept' or the first failing rule, in the order of CURATION_RULES (the ball's own faults first,
so a fault is named for what the ball did, then the path, then the quality of the input data); all
failing rules are listed in 'reasons'.

Frames: every table here is on the ball3d table's frames (the 100 Hz camera clock, one row per frame,
NaN where the ball was not seen); 'index' / '*_frame' columns are row positions in it. Labels and strike
points are in the mirrored frame (docs/architecture.md): the hitter at +y, the ball travelling towards -y.
"""

from dataclasses import dataclass

import numpy as np
import pandas as pd

from pingpong.common.config import Settings
from pingpong.curation.labels import (
    labels_of_path,
    measured_strike_point,
    mirror_points,
    strike_point_from_labels,
)
from pingpong.curation.schemas import CANDIDATE_COLUMNS, CURATION_RULES, SEGMENTS
from pingpong.curation.tracks import (
    JOINT_VIEWS,
    JOINT_XYZ,
    OPPONENT_END,
    PLAYER_END,
    PLAYER_SIGN,
    paddle_arrays,
    per_player,
    runs,
)
from pingpong.frames import MODEL_JOINT_IDS, STRIKE_Y, region_of

# ------------------------------------------------------------------------------------------ alignment











# ------------------------------------------------------------------------------------------ filtering









# ------------------------------------------------------------------------------------------ segments

def _flight_end(finite: np.ndarray, start: int, stop: int, max_gap: int) -> int:
    """Last seen frame of the flight that starts at `start`, before `stop` (exclusive): the flight ends at
    the first run of more than max_gap unseen frames."""
    seen = np.flatnonzero(finite[start:stop])
    if len(seen) == 0:
        return start
    jumps = np.flatnonzero(np.diff(seen) > max_gap + 1)
    return start + int(seen[jumps[0]] if len(jumps) else seen[-1])


def find_segments(ball: pd.DataFrame, events: pd.DataFrame, session: str = "", flight_gap_s: float = 0.15,
                  strike_tolerance: float = 0.05, fs_hz: float = 100.0) -> pd.DataFrame:
    """Candidate hits of a session, one row per detected hit, with their segment and post-hit events.

    start_frame: the incoming net crossing towards the hitter since the previous hit (-1: none, e.g. a
    serve); end_frame: the last frame of the post-hit path (the first past the opponent's strike line,
    else flight_end_frame); flight_end_frame: the last seen frame up to the next hit's contact frame,
    or before the ball is lost for more than flight_gap_s. post_bounce_sides: the table halves of the
    bounces up to flight_end_frame, in order, ';'-joined; crosses_net: the ball crossed the net away
    from the hitter; reaches_strike_line: a sample past the strike line, or the path's last seen sample
    within strike_tolerance (m) of it (an opponent meeting the ball just past the line can hide the
    sample beyond it behind the paddle). The hitter is the player whose paddle was nearest at the hit
    (detect_events).
    """
    xyz = ball[["x", "y", "z"]].to_numpy(float)
    finite = np.isfinite(xyz).all(axis=1)
    hits = events[events["kind"] == "hit"].reset_index(drop=True)
    bounces = events[events["kind"] == "bounce"]
    net = events[events["kind"] == "net"]
    max_gap = int(round(flight_gap_s * fs_hz))
    rows = []
    for h, hit in hits.iterrows():
        i = int(hit["index"])
        hitter = hit["player"]
        previous = int(hits["index"][h - 1]) if h > 0 else -1
        # the next hit's contact sample ends this flight too: a ball met just past the strike line has no
        # other sample beyond it
        following = int(hits["index"][h + 1]) + 1 if h + 1 < len(hits) else len(ball)
        incoming = net[(net["index"] > previous) & (net["index"] <= i) & (net["side"] == PLAYER_END[hitter])]
        flight_end = _flight_end(finite, i, following, max_gap)
        in_flight = slice(i + 1, flight_end + 1)
        post_bounces = bounces[(bounces["index"] > i) & (bounces["index"] <= flight_end)]
        crossed = ((net["index"] > i) & (net["index"] <= flight_end) & (net["side"] == OPPONENT_END[hitter]))
        # the path in the hitter's frame (travelling towards -y), to the first sample past the strike line
        y_own = xyz[:, 1] * PLAYER_SIGN[hitter]
        past = np.flatnonzero(finite[in_flight] & (y_own[in_flight] <= STRIKE_Y))
        end = i + 1 + int(past[0]) if len(past) else flight_end
        near_line = finite[end] and y_own[end] <= STRIKE_Y + strike_tolerance
        rows.append({
            "session": session, "hit": h, "hitter": hitter, "t_hit_ns": int(hit["time_ns"]), "hit_frame": i,
            "start_frame": int(incoming["index"].iloc[-1]) if len(incoming) else -1, "end_frame": end,
            "flight_end_frame": flight_end, "post_bounce_sides": ";".join(post_bounces["side"]),
            "n_opponent_bounces": int((post_bounces["side"] == OPPONENT_END[hitter]).sum()),
            "crosses_net": bool(crossed.any()), "reaches_strike_line": bool(len(past) or near_line),
            "n_path_points": int(finite[i:end + 1].sum())})
    return pd.DataFrame(rows, columns=list(CANDIDATE_COLUMNS))


# ------------------------------------------------------------------------------------------ curation

def strike_point(path: np.ndarray) -> tuple[float, float]:
    """(x, z) where a mirrored path (n, 3) of seen samples crosses the strike line (measured_strike_point);
    a path ending short of it is extended along its last step (find_segments allows that only within
    its strike_tolerance)."""
    x, z = measured_strike_point(path)
    if np.isnan(x) and len(path) >= 2 and path[-2, 1] > path[-1, 1]:
        step = path[-1] - path[-2]
        x, _, z = path[-1] + step * (path[-1, 1] - STRIKE_Y) / -step[1]
    return float(x), float(z)


def missing_joints(pose: pd.DataFrame, player: str, time_ns: np.ndarray, min_views: int = 2) -> np.ndarray:
    """(T, 8) bool: where each of the player's model joints is missing (unseen, or removed by clean_pose)
    or seen by fewer than min_views cameras."""
    joints = per_player(pose, player, JOINT_XYZ, time_ns).reshape(len(time_ns), len(MODEL_JOINT_IDS), 3)
    views = per_player(pose, player, JOINT_VIEWS, time_ns)
    return ~np.isfinite(joints).all(axis=2) | ~(np.nan_to_num(views, nan=0.0) >= min_views)


def assign_rallies(segments: pd.DataFrame, ball: pd.DataFrame, rally_gap_s: float = 0.4,
                   fs_hz: float = 100.0) -> np.ndarray:
    """Rally id (0, 1, ...) of each candidate, in hit order: a new rally starts after a gap of more than
    rally_gap_s without the ball since the previous hit, or after a hit that was a fault (the 'fault'
    column: net, out or double bounce), which ends a rally by the rules."""
    finite = np.isfinite(ball[["x", "y", "z"]].to_numpy(float)).all(axis=1)
    starts, stops = runs(~finite)
    long_gaps = stops - starts > rally_gap_s * fs_hz
    rally = np.zeros(len(segments), int)
    frames = segments["hit_frame"].to_numpy(int)
    faults = segments["fault"].to_numpy(bool)
    for k in range(1, len(segments)):
        gap = (long_gaps & (starts > frames[k - 1]) & (stops <= frames[k])).any()
        rally[k] = rally[k - 1] + int(gap or faults[k - 1])
    return rally


@dataclass(frozen=True)
class CurationRules(Settings):
    """The curation thresholds (config curation.rules; curate_segments says what each means)."""

    window_frames: int
    max_ball_missing_frames: int
    max_joint_missing_frames: int
    max_paddle_missing_frames: int
    min_path_points: int
    min_side_points: int
    min_joint_views: int
    min_strike_z: float  # m
    rally_gap_s: float


def curate_segments(segments: pd.DataFrame, ball: pd.DataFrame, pose: pd.DataFrame, paddle: pd.DataFrame,
                    rules: CurationRules, fs_hz: float = 100.0) -> pd.DataFrame:
    """The candidates with rally ids, data-quality counts, labels, strike points, region and decision.

    Rules (CURATION_RULES order): 'net' the ball does not cross the net away from the hitter; 'out' its
    first bounce after the hit is not on the opponent's half (or it has none); 'double_bounce' two or
    more bounces there; 'no_strike_line' the path does not reach the strike line, or reaches it lower
    than min_strike_z (m; the table surface: a ball falling to the floor beside the table); 'few_points'
    fewer than min_path_points seen samples on the path or fewer than min_side_points on either side of
    the net (each label slope needs its own); 'no_incoming' no net crossing towards the hitter before
    the hit (the segment has no start, e.g. a serve); 'short_history' fewer than window_frames frames
    recorded up to the hit; 'ball_gaps' / 'pose_gaps' / 'paddle_gaps' more than max_*_frames of the
    window_frames frames up to the hit without the ball / without one of the hitter's joints
    (missing_joints; counted joint by joint, as the gaps are filled joint by joint) / without the
    hitter's paddle. Labels (a1, a2, b) are fitted to the mirrored filtered path from the hit to
    end_frame; strike_x, strike_z: its measured crossing of y = STRIKE_Y; strike_x_labels: the labels'
    x there; region: region_of(strike_x_labels), the strike point the model's labels stand for.
    """
    time_ns = ball["time_ns"].to_numpy(np.int64)
    xyz = ball[["x", "y", "z"]].to_numpy(float)
    finite = np.isfinite(xyz).all(axis=1)
    out = segments.copy()
    no_joint = {p: missing_joints(pose, p, time_ns, rules.min_joint_views) for p in PLAYER_END}
    no_paddle = {p: ~np.isfinite(paddle_arrays(paddle, p, time_ns)).all(axis=1) for p in PLAYER_END}
    columns = {c: [] for c in ("ball_missing_frames", "joint_missing_frames", "paddle_missing_frames", "a1",
                               "a2", "b", "strike_x", "strike_z", "fault", "reasons")}
    for seg in segments.itertuples(index=False):
        i, hitter = seg.hit_frame, seg.hitter
        window = slice(max(i - rules.window_frames + 1, 0), i + 1)
        counts = {"ball_missing_frames": int((~finite[window]).sum()),
                  "joint_missing_frames": int(no_joint[hitter][window].sum(axis=0).max()),
                  "paddle_missing_frames": int(no_paddle[hitter][window].sum())}
        path = xyz[i:seg.end_frame + 1]
        path = path[np.isfinite(path).all(axis=1)]
        path = path if hitter == "near" else mirror_points(path)
        n_sides = ((path[:, 1] > 0).sum(), (path[:, 1] < 0).sum())
        bounce_sides = seg.post_bounce_sides.split(";") if seg.post_bounce_sides else []
        labels = labels_of_path(path) if min(n_sides) >= 2 else (np.nan,) * 3
        strike = strike_point(path) if seg.reaches_strike_line else (np.nan, np.nan)
        failed = {
            "net": not seg.crosses_net,
            "out": not bounce_sides or bounce_sides[0] != OPPONENT_END[hitter],
            "double_bounce": seg.n_opponent_bounces >= 2,
            "no_strike_line": not (seg.reaches_strike_line and strike[1] >= rules.min_strike_z),
            "few_points": len(path) < rules.min_path_points or min(n_sides) < rules.min_side_points,
            "no_incoming": seg.start_frame < 0,
            "short_history": i + 1 < rules.window_frames,
            "ball_gaps": counts["ball_missing_frames"] > rules.max_ball_missing_frames,
            "pose_gaps": counts["joint_missing_frames"] > rules.max_joint_missing_frames,
            "paddle_gaps": counts["paddle_missing_frames"] > rules.max_paddle_missing_frames,
        }
        for name, count in counts.items():
            columns[name].append(count)
        columns["fault"].append(failed["net"] or failed["out"] or failed["double_bounce"])
        columns["reasons"].append(";".join(r for r in CURATION_RULES if failed[r]))
        for name, value in zip(("a1", "a2", "b"), labels, strict=True):
            columns[name].append(value)
        columns["strike_x"].append(strike[0])
        columns["strike_z"].append(strike[1])
    out = out.assign(**columns)
    out["rally"] = assign_rallies(out, ball, rules.rally_gap_s, fs_hz)
    out["strike_x_labels"] = strike_point_from_labels(out["a1"].to_numpy(float), out["a2"].to_numpy(float),
                                                      out["b"].to_numpy(float))
    out["region"] = np.where(np.isfinite(out["strike_x_labels"]), region_of(out["strike_x_labels"]), "")
    out["decision"] = [r.split(";")[0] if r else "kept" for r in out["reasons"]]
    return out.drop(columns="fault")[list(SEGMENTS.columns)]
