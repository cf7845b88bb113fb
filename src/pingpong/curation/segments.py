"""Filtering a session, finding candidate hits (the paper's segments) and curating them.

A segment runs from the ball crossing the net towards a player to that player's strike (the incoming
part, with the hitter's pre-hit frames) and on through the post-hit flight, until the ball crosses the
strike line on the opponent's side, the next hit, or the flight ends. Every candidate keeps its
decision: 'kept' or the first failing rule, in the order of CURATION_RULES (the ball's own faults first,
so a fault is named for what the ball did, then the path, then the quality of the input data); all
failing rules are listed in 'reasons'.

Frames: every table here is on the ball3d table's frames (the 100 Hz camera clock, one row per frame,
NaN where the ball was not seen); 'index' / '*_frame' columns are row positions in it. Labels and strike
points are in the mirrored frame (DESIGN.md): the hitter at +y, the ball travelling towards -y.
"""

import numpy as np
import pandas as pd

from pingpong.common.artifacts import Schema
from pingpong.curation.events import detect_bounces, detect_hits, detect_net_crossings
from pingpong.curation.filtering import lowpass, lowpass_between_events
from pingpong.curation.labels import (
    labels_of_path,
    measured_strike_point,
    mirror_points,
    strike_point_from_labels,
)
from pingpong.frames import MODEL_JOINT_IDS, ROT_COLUMNS, STRIKE_Y, region_of

PLAYER_END = {"near": "+y", "far": "-y"}  # the end of the table each player stands at
OPPONENT_END = {"near": "-y", "far": "+y"}
PLAYER_SIGN = {"near": 1.0, "far": -1.0}
JOINT_XYZ = [f"j{j:02d}_{a}" for j in MODEL_JOINT_IDS for a in "xyz"]
JOINT_VIEWS = [f"j{j:02d}_n" for j in MODEL_JOINT_IDS]
PADDLE_VALUES = ["px", "py", "pz", *ROT_COLUMNS]
# pairs of model joints (positions in MODEL_JOINT_IDS) whose distance is a rigid bone or the torso's width
BONES = ((0, 1), (1, 2), (3, 4), (4, 5), (0, 3), (6, 7), (0, 6), (3, 7))

EVENT_COLUMNS = ("kind", "index", "time_ns", "player", "side", "x", "y", "z")
EVENTS = Schema("ball_events", 1, EVENT_COLUMNS)
CURATION_RULES = ("net", "out", "double_bounce", "no_strike_line", "few_points", "no_incoming",
                  "short_history", "ball_gaps", "pose_gaps", "paddle_gaps")
CANDIDATE_COLUMNS = (  # find_segments
    "session", "hit", "hitter", "t_hit_ns", "hit_frame", "start_frame", "end_frame", "flight_end_frame",
    "post_bounce_sides", "n_opponent_bounces", "crosses_net", "reaches_strike_line", "n_path_points")
SEGMENTS = Schema("segments", 1, (  # curate_segments
    *CANDIDATE_COLUMNS, "rally", "ball_missing_frames", "joint_missing_frames", "paddle_missing_frames",
    "a1", "a2", "b", "strike_x", "strike_z", "strike_x_labels", "region", "decision", "reasons"))


# ------------------------------------------------------------------------------------------ alignment

def frame_seconds(time_ns) -> np.ndarray:
    """Frame times in s from the first frame (float64 keeps the session's ~1e18 ns epoch exact this way)."""
    time_ns = np.asarray(time_ns, np.int64)
    return (time_ns - time_ns[0]) * 1e-9


def per_player(table: pd.DataFrame, player: str, columns, time_ns: np.ndarray) -> np.ndarray:
    """One player's columns (T, len(columns)) on the frames time_ns; NaN on frames the table lacks."""
    rows = table[table["player"] == player].drop_duplicates("time_ns").set_index("time_ns")
    return rows.reindex(time_ns)[list(columns)].to_numpy(float, copy=True)


def paddle_arrays(paddle: pd.DataFrame, player: str, time_ns: np.ndarray) -> np.ndarray:
    """A player's paddle (T, 12): position, rotation row-major; NaN where OptiTrack had a gap."""
    values = per_player(paddle, player, PADDLE_VALUES, time_ns)
    valid = per_player(paddle.assign(valid=paddle["valid"].astype(float)), player, ["valid"], time_ns)[:, 0]
    values[~(valid > 0)] = np.nan
    return values


def _fill_short_gaps(values: np.ndarray, max_gap: int) -> np.ndarray:
    """Columns of values (T, D) linearly interpolated across NaN runs of at most max_gap samples."""
    out = values.copy()
    good = np.isfinite(values).all(axis=1)
    if good.sum() < 2:
        return out
    short = np.zeros(len(values), bool)
    for start, stop in zip(*_runs(~good), strict=True):
        short[start:stop] = stop - start <= max_gap and start > 0 and stop < len(values)
    k = np.arange(len(values))
    for d in range(values.shape[1]):
        out[short, d] = np.interp(k[short], k[good], values[good, d])
    return out


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and stops ([start, stop)) of the True runs in a boolean mask."""
    edges = np.diff(np.concatenate([[0], np.asarray(mask, np.int8), [0]]))
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)


# ------------------------------------------------------------------------------------------ filtering

def drop_ball_outliers(ball3d: pd.DataFrame, max_speed: float = 40.0, margin: float = 0.05,
                       neighbours: int = 2, fs_hz: float = 100.0) -> pd.DataFrame:
    """ball3d with the samples no neighbour confirms set unseen (x, y, z NaN, n_views 0): a sample is
    kept when a seen sample within `neighbours` frames lies within max_speed (m/s, above a smash) * dt
    + margin (m) of it. A triangulation onto a wrong pair of detections lands metres off its flight; an
    isolated sample cannot be checked and is dropped too."""
    xyz = ball3d[["x", "y", "z"]].to_numpy(float)
    confirmed = np.zeros(len(xyz), bool)
    for k in range(1, neighbours + 1):
        step = np.linalg.norm(xyz[k:] - xyz[:-k], axis=1) <= max_speed * k / fs_hz + margin  # NaN: False
        confirmed[k:] |= step
        confirmed[:-k] |= step
    out = ball3d.copy()
    dropped = ~confirmed & np.isfinite(xyz).all(axis=1)
    out.loc[dropped, ["x", "y", "z"]] = np.nan
    out.loc[dropped, "n_views"] = 0
    return out


def detect_events(ball3d: pd.DataFrame, paddle: pd.DataFrame, hit_max_distance: float = 0.3,
                  paddle_fill_s: float = 0.25, fs_hz: float = 100.0) -> pd.DataFrame:
    """Hits, table bounces and net crossings of a session's raw 3D ball (EVENTS columns, in time order).

    kind: 'hit' (player: the nearest paddle's; side: that player's end), 'bounce' (side: the table half)
    or 'net' (side: the direction the ball goes). index: the ball3d row; time_ns: the sub-frame event
    time. Paddle positions are interpolated across OptiTrack gaps of up to paddle_fill_s for this only:
    a paddle lost for a few frames around the contact must not lose the hit.
    """
    time_ns = ball3d["time_ns"].to_numpy(np.int64)
    t = frame_seconds(time_ns)
    ball = ball3d[["x", "y", "z"]].to_numpy(float)
    fill = int(round(paddle_fill_s * fs_hz))
    paddles = {p: _fill_short_gaps(paddle_arrays(paddle, p, time_ns)[:, :3], fill) for p in PLAYER_END}
    # span: 3 samples either side at 100 Hz; at 0.03 s rounding in t can leave the third one out, and a
    # contact frame lost behind the paddle then leaves one side a single sample, too few to time the hit
    hits = detect_hits(t, ball, paddles, max_distance=hit_max_distance, span=3.5 / fs_hz)
    hits = hits.assign(kind="hit", side=hits["player"].map(PLAYER_END))
    bounces = detect_bounces(t, ball).assign(kind="bounce", player="")
    net = detect_net_crossings(t, ball)
    net = net.assign(kind="net", player="", side=net["direction"],
                     **{a: ball[net["index"].to_numpy(int), k] for k, a in enumerate("xyz")})
    found = [e for e in (hits, bounces, net) if len(e)]
    if not found:
        return pd.DataFrame({"kind": pd.Series(dtype=str), "index": pd.Series(dtype=np.int64),
                             "time_ns": pd.Series(dtype=np.int64), "player": pd.Series(dtype=str),
                             "side": pd.Series(dtype=str), **{a: pd.Series(dtype=float) for a in "xyz"}})
    events = pd.concat(found, ignore_index=True)
    events["time_ns"] = time_ns[0] + np.round(events["time"].to_numpy() * 1e9).astype(np.int64)
    events["index"] = events["index"].astype(np.int64)
    return events.sort_values(["index", "time_ns"], kind="stable").reset_index(drop=True)[list(EVENT_COLUMNS)]


def clean_pose(pose3d: pd.DataFrame, max_bone_error: float = 0.10) -> pd.DataFrame:
    """pose3d with bad joints removed (coordinates NaN, views 0): a joint is bad on a frame where every
    bone (BONES) it belongs to is longer or shorter than that bone's median over the player's session by
    more than max_bone_error (m), e.g. a joint triangulated onto the other arm or another person. On the
    raw pose, before the low-pass, which would smear one such frame over its neighbours."""
    out = pose3d.copy()
    for player in out["player"].unique():
        rows = (out["player"] == player).to_numpy()
        joints = out.loc[rows, JOINT_XYZ].to_numpy(float).reshape(-1, len(MODEL_JOINT_IDS), 3)
        lengths = np.stack([np.linalg.norm(joints[:, a] - joints[:, b], axis=1) for a, b in BONES], axis=1)
        with np.errstate(invalid="ignore"):
            off = np.abs(lengths - np.nanmedian(lengths, axis=0)) > max_bone_error
        bad = np.stack([off[:, [k for k, bone in enumerate(BONES) if j in bone]].all(axis=1)
                        for j in range(len(MODEL_JOINT_IDS))], axis=1)  # (T, 8)
        bad_xyz = np.repeat(bad, 3, axis=1)
        out.loc[rows, JOINT_XYZ] = np.where(bad_xyz, np.nan, out.loc[rows, JOINT_XYZ].to_numpy(float))
        out.loc[rows, JOINT_VIEWS] = np.where(bad, 0, out.loc[rows, JOINT_VIEWS].to_numpy())
    return out


def filter_session(ball3d: pd.DataFrame, pose3d: pd.DataFrame, paddle: pd.DataFrame, cutoff_ball_hz: float,
                   cutoff_pose_hz: float, fs_hz: float = 100.0, hit_max_distance: float = 0.3,
                   paddle_fill_s: float = 0.25, max_bone_error: float = 0.10,
                   ) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """(ball_filtered, pose_filtered, events) of one session.

    Ball samples no neighbour confirms are dropped first (drop_ball_outliers). Events are found on the
    raw ball (a low-pass would round off the turns they are found by); the ball is then low-passed piece
    by piece between its hits and bounces, the pose joint by joint per player after clean_pose (bad
    joints become gaps, which stay NaN). The tables keep their columns (ball3d's and pose3d's), rows
    sorted by time (ball: one per frame).
    """
    ball3d = ball3d.sort_values("time_ns").reset_index(drop=True)
    if ball3d["time_ns"].duplicated().any():
        raise ValueError("ball3d: more than one row on a frame; expected one row per camera frame")
    ball3d = drop_ball_outliers(ball3d, fs_hz=fs_hz)
    events = detect_events(ball3d, paddle, hit_max_distance, paddle_fill_s, fs_hz)
    cuts = events.loc[events["kind"].isin(["hit", "bounce"]), "index"].to_numpy(int)
    ball = ball3d.copy()
    ball[["x", "y", "z"]] = lowpass_between_events(frame_seconds(ball3d["time_ns"]),
                                                   ball3d[["x", "y", "z"]].to_numpy(float), cuts,
                                                   cutoff_ball_hz, fs_hz)
    pose3d = clean_pose(pose3d, max_bone_error)
    parts = []
    for _, rows in pose3d.sort_values(["player", "time_ns"], kind="stable").groupby("player", sort=False):
        rows = rows.copy()
        rows[JOINT_XYZ] = lowpass(rows[JOINT_XYZ].to_numpy(float), cutoff_pose_hz, fs_hz)
        parts.append(rows)
    pose = pd.concat(parts).sort_values(["time_ns", "player"], kind="stable").reset_index(drop=True)
    return ball, pose[list(pose3d.columns)], events


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


def assign_rallies(segments: pd.DataFrame, ball: pd.DataFrame, rally_gap_s: float = 1.0,
                   fs_hz: float = 100.0) -> np.ndarray:
    """Rally id (0, 1, ...) of each candidate, in hit order: a new rally starts after a gap of more than
    rally_gap_s without the ball since the previous hit, or after a hit that was a fault (the 'fault'
    column: net, out or double bounce), which ends a rally by the rules."""
    finite = np.isfinite(ball[["x", "y", "z"]].to_numpy(float)).all(axis=1)
    starts, stops = _runs(~finite)
    long_gaps = stops - starts > rally_gap_s * fs_hz
    rally = np.zeros(len(segments), int)
    frames = segments["hit_frame"].to_numpy(int)
    faults = segments["fault"].to_numpy(bool)
    for k in range(1, len(segments)):
        gap = (long_gaps & (starts > frames[k - 1]) & (stops <= frames[k])).any()
        rally[k] = rally[k - 1] + int(gap or faults[k - 1])
    return rally


def curate_segments(segments: pd.DataFrame, ball: pd.DataFrame, pose: pd.DataFrame, paddle: pd.DataFrame, *,
                    window_frames: int = 40, max_ball_missing_frames: int = 8,
                    max_joint_missing_frames: int = 8, max_paddle_missing_frames: int = 8,
                    min_path_points: int = 12, min_side_points: int = 4, min_joint_views: int = 2,
                    min_strike_z: float = 0.0, rally_gap_s: float = 1.0, fs_hz: float = 100.0,
                    ) -> pd.DataFrame:
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
    no_joint = {p: missing_joints(pose, p, time_ns, min_joint_views) for p in PLAYER_END}
    no_paddle = {p: ~np.isfinite(paddle_arrays(paddle, p, time_ns)).all(axis=1) for p in PLAYER_END}
    columns = {c: [] for c in ("ball_missing_frames", "joint_missing_frames", "paddle_missing_frames", "a1",
                               "a2", "b", "strike_x", "strike_z", "fault", "reasons")}
    for seg in segments.itertuples(index=False):
        i, hitter = seg.hit_frame, seg.hitter
        window = slice(max(i - window_frames + 1, 0), i + 1)
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
            "no_strike_line": not (seg.reaches_strike_line and strike[1] >= min_strike_z),
            "few_points": len(path) < min_path_points or min(n_sides) < min_side_points,
            "no_incoming": seg.start_frame < 0,
            "short_history": i + 1 < window_frames,
            "ball_gaps": counts["ball_missing_frames"] > max_ball_missing_frames,
            "pose_gaps": counts["joint_missing_frames"] > max_joint_missing_frames,
            "paddle_gaps": counts["paddle_missing_frames"] > max_paddle_missing_frames,
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
    out["rally"] = assign_rallies(out, ball, rally_gap_s, fs_hz)
    out["strike_x_labels"] = strike_point_from_labels(out["a1"].to_numpy(float), out["a2"].to_numpy(float),
                                                      out["b"].to_numpy(float))
    out["region"] = np.where(np.isfinite(out["strike_x_labels"]), region_of(out["strike_x_labels"]), "")
    out["decision"] = [r.split(";")[0] if r else "kept" for r in out["reasons"]]
    return out.drop(columns="fault")[list(SEGMENTS.columns)]
