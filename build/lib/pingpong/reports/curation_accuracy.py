"""Curation against the twin's truth: events, decisions, filtering and labels, one row per quantity.

Only twin runs have truth; the rows are what reports/tables/curation_accuracy.md shows, measured the way
tests/test_segments.py measures them on a simulated session. Every function takes one tuple of tables
per session and pools the sessions.

Matching (all within one camera frame, FRAME_NS):
- a true event is found when a detected event of the same kind lies within a frame of it; a detected
  event is spurious when no true event of its kind does. Serves are left out of the hits to find (the
  twin's ball appears at the serve, so no incoming flight shows it), and so are bounces a 100 Hz camera
  cannot see (falling slower than 1 m/s just before: a dead ball's last hops); both still make a
  detection near them real.
- a candidate's true shot is the shot of its session hit nearest to it, if within a frame; a candidate
  with none is not a true hit and counts as a disagreement.
"""

import numpy as np
import pandas as pd

from pingpong.frames import FRAME_NS
from pingpong.reports.tables import threshold_row as _row

FAULTS = ("net", "out", "double_bounce")  # the twin's faults, named alike by curation
DATA_RULES = ("few_points", "no_incoming", "short_history", "ball_gaps", "pose_gaps", "paddle_gaps")
VISIBLE_BOUNCE_VZ = -1.0  # m/s: a bounce counts as visible when the ball falls at least this fast


def match_times(true_ns, found_ns, tol_ns: int = FRAME_NS) -> tuple[np.ndarray, np.ndarray]:
    """(true times with a found one within tol_ns, found times with a true one within tol_ns)."""
    true_ns, found_ns = np.asarray(true_ns, np.int64), np.asarray(found_ns, np.int64)
    if len(true_ns) == 0 or len(found_ns) == 0:
        return np.zeros(len(true_ns), bool), np.zeros(len(found_ns), bool)
    d = np.abs(true_ns[:, None] - found_ns[None, :])
    return d.min(axis=1) <= tol_ns, d.min(axis=0) <= tol_ns


def nearest_shot(shots: pd.DataFrame, t_hit_ns, tol_ns: int = FRAME_NS) -> np.ndarray:
    """Row position in `shots` of each candidate's true shot (nearest t_hit_ns within tol_ns), else -1."""
    t_hit_ns = np.asarray(t_hit_ns, np.int64)
    if len(shots) == 0 or len(t_hit_ns) == 0:
        return np.full(len(t_hit_ns), -1)
    d = np.abs(shots["t_hit_ns"].to_numpy(np.int64)[:, None] - t_hit_ns[None, :])
    return np.where(d.min(axis=0) <= tol_ns, d.argmin(axis=0), -1)


def event_matches(detected: pd.DataFrame, events: pd.DataFrame, shots: pd.DataFrame,
                  ball: pd.DataFrame) -> dict:
    """One session's found (true) and real (detected) flags for hits and bounces."""
    served = shots.loc[shots["shot"] == 0, "t_hit_ns"]
    true_hits = events[events["kind"] == "hit"]
    found_hits = detected.loc[detected["kind"] == "hit", "time_ns"]
    hits_found, _ = match_times(true_hits.loc[~true_hits["time_ns"].isin(served), "time_ns"], found_hits)
    _, hits_real = match_times(true_hits["time_ns"], found_hits)
    bounces = events[events["kind"] == "bounce"]
    vz = np.interp(bounces["time_ns"].to_numpy(np.int64) - 2_000_000, ball["time_ns"], ball["vz"])
    found_bounces = detected.loc[detected["kind"] == "bounce", "time_ns"]
    bounces_found, _ = match_times(bounces["time_ns"][vz < VISIBLE_BOUNCE_VZ], found_bounces)
    _, bounces_real = match_times(bounces["time_ns"], found_bounces)
    return {"hits_found": hits_found, "hits_real": hits_real,
            "bounces_found": bounces_found, "bounces_real": bounces_real}


def event_rows(sessions: list[tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame, pd.DataFrame]]) -> list[dict]:
    """Recall and spurious share of hits and bounces, pooled; sessions: (detected, events, shots, ball)."""
    m = [event_matches(*s) for s in sessions]
    flags = {k: np.concatenate([x[k] for x in m]) for k in m[0]}
    rows = []
    for kind in ("hits", "bounces"):
        found, real = flags[f"{kind}_found"], flags[f"{kind}_real"]
        rows.append(_row(f"true {kind} found within a frame", 100 * found.mean(), "%", 99.0, "at least"))
        rows.append(_row(f"spurious detected {kind}", 100 * (~real).mean(), "% of detected", 1.0))
    return rows


def expected_decisions(shots: pd.DataFrame, events: pd.DataFrame, shot_of: np.ndarray) -> np.ndarray:
    """The decision the truth calls for at each candidate (shot_of from nearest_shot; -1: 'not_a_hit').

    'ok' -> 'kept', a fault -> that fault, a 'miss' stays 'miss' (no true hit: no decision fits), and
    as in tests/test_segments.py an 'out' ball that bounced once, on the opponent's half, then fell
    beside the table -> 'no_strike_line' (curation names it for what makes it unusable).
    """
    expected = np.full(len(shot_of), "not_a_hit", dtype=object)
    matched = shot_of >= 0
    truth = shots.iloc[shot_of[matched]]
    outcome = truth["outcome"].replace({"ok": "kept"}).to_numpy().astype(object)
    bounces = events[events["kind"] == "bounce"].groupby(["rally", "shot"])["side"].agg(list)
    far_end = np.where(truth["side"].to_numpy() > 0, "-y", "+y")
    one_good = np.array([bounces.get((r, s), []) == [f] for r, s, f in
                         zip(truth["rally"], truth["shot"], far_end, strict=True)], bool)
    expected[matched] = np.where((outcome == "out") & one_good, "no_strike_line", outcome)
    return expected


def decision_table(sessions: list[tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]]) -> pd.DataFrame:
    """Each candidate's decision beside the one the truth expects (expected_decisions), pooled;
    sessions: (segments, shots, events) of one session. 'data_quality': a data-quality rejection (gaps,
    too few points, ...) of a true 'ok' return, which says nothing about faults."""
    parts = []
    for segments, shots, events in sessions:
        shot_of = nearest_shot(shots, segments["t_hit_ns"])
        parts.append(pd.DataFrame({"decision": segments["decision"].to_numpy().astype(object),
                                   "expected": expected_decisions(shots, events, shot_of)}))
    table = pd.concat(parts, ignore_index=True)
    table["data_quality"] = table["decision"].isin(DATA_RULES) & (table["expected"] == "kept")
    return table


def decision_rows(table: pd.DataFrame) -> list[dict]:
    """Agreement of decision_table: data-quality rejections of true 'ok' returns are left out; one of a
    true fault means the fault was missed, a disagreement; a candidate that is no true hit disagrees."""
    decision, expected = table["decision"].to_numpy(), table["expected"].to_numpy()
    agree = (decision == expected)[~table["data_quality"].to_numpy()]
    kept, faults = decision == "kept", np.isin(expected, FAULTS)
    return [
        _row("candidates that are true hits", 100 * (expected != "not_a_hit").mean(), "%", 99.0, "at least"),
        _row("decisions agreeing with the twin's outcome", 100 * agree.mean(), "% of candidates", 98.0,
             "at least"),
        _row("kept candidates that are true ok returns", 100 * (expected[kept] == "kept").mean(), "%", 98.0,
             "at least"),
        _row("true faults rejected as that fault", 100 * (decision[faults] == expected[faults]).mean(), "%",
             98.0, "at least"),
    ]


def in_flight_errors(ball3d: pd.DataFrame, filtered: pd.DataFrame,
                     true_xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unfiltered, filtered) distances (m) to the true ball on frames where the truth and both exist."""
    raw = np.linalg.norm(ball3d[["x", "y", "z"]].to_numpy() - true_xyz, axis=1)
    low = np.linalg.norm(filtered[["x", "y", "z"]].to_numpy() - true_xyz, axis=1)
    both = np.isfinite(raw) & np.isfinite(low)
    return raw[both], low[both]


def filtering_rows(errors: list[tuple[np.ndarray, np.ndarray]]) -> list[dict]:
    """Median in-flight ball error before and after filtering, pooled; errors: in_flight_errors each."""
    raw = 1e3 * float(np.median(np.concatenate([e[0] for e in errors])))
    low = 1e3 * float(np.median(np.concatenate([e[1] for e in errors])))
    return [_row("unfiltered 3D ball error in flight (median)", raw, "mm", 5.0),
            _row("filtered 3D ball error in flight (median)", low, "mm", raw)]


def label_rows(sessions: list[tuple[pd.DataFrame, pd.DataFrame]]) -> list[dict]:
    """Kept candidates: the labels' strike point against the measured crossing and the measured one
    against the truth (the twin's strike_x, mirrored); sessions: (segments, shots)."""
    fit, measured = [], []
    for segments, shots in sessions:
        kept = segments[segments["decision"] == "kept"]
        fit.append(np.abs(kept["strike_x_labels"] - kept["strike_x"]).to_numpy())
        shot_of = nearest_shot(shots, kept["t_hit_ns"])
        truth = shots.iloc[shot_of[shot_of >= 0]]
        true_x = truth["strike_x"].to_numpy() * truth["side"].to_numpy()  # a far hitter's x flips
        measured.append(np.abs(kept["strike_x"].to_numpy()[shot_of >= 0] - true_x))
    return [_row("label strike point vs measured crossing (median)",
                 100 * float(np.nanmedian(np.concatenate(fit))), "cm", 2.0),
            _row("measured strike point vs truth (median)",
                 100 * float(np.nanmedian(np.concatenate(measured))), "cm", 0.5)]
