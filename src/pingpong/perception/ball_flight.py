"""Which triangulated balls are a ball in flight, and which are phantoms (issue 36: "No ball is a result").

A 3D point whose views agree (the triangulation's reprojection gate) can still be no ball: two false
detections that happen to meet within the gate, or one orange thing that every camera sees (a face, a
cap, a shirt print) and that triangulates as consistently as a ball. A ball in play is told apart by its
motion: from one frame to the next it follows a flight, whose acceleration is gravity plus the air's
drag and lift, and these grow with the square of the speed (twin.ball: a = g - k_D |v| v + lift, the
lift across v and at most 0.14 |v|^2 per m there). So:

1. Tracks: each seen point continues the open track whose last point is nearest, among those at most
   `max_gap_frames` unseen frames before it and within `max_speed` (m/s) of travel plus `link_margin`
   (m); else it starts a track. A phantom between two of the ball's points makes a track of its own.
2. Ballistic windows: every run of `window_frames` consecutive track points is fitted with a quadratic
   in time per axis (constant acceleration: a flight's changes little in 0.1 s). A window is ballistic
   when the fit's RMS residual is within `max_residual_m`, its speed v (at its middle) at least
   `min_speed`, and its acceleration less g lies within `accel_tol` of what the air can do: a drag
   between 0 and `drag_per_m` |v|^2 against v, a lift up to `lift_per_m` |v|^2 across it. A chance
   coincidence of false detections does not last `window_frames` frames on a smooth path; a head, a hand
   or an object at rest barely accelerates, where a ball falls at g.
3. A point is in flight when a ballistic window of its own track holds it or lies within `event_frames`
   points of it along the track: a bounce or a hit turns the ball abruptly, so no window fits across it,
   and the few points beside the contact are vouched for by the flights on either side.
4. A flight is a run of at least `min_flight_frames` consecutive track points in flight: one chance window
   (a hand swung at 6 m/s, 2 views, fitted 5 mm apart) covers at most window_frames + 2 event_frames
   points, a ball in play flies longer between two hits.
5. A session has a ball only when its longest flight spans `rally_frames` points: a rally's serve alone
   flies 0.5 s and more, bounces included. A hand falling almost freely (a ball held in it, say) passed
   for 0.2-0.3 s at a time on the twin; so does the session have no ball, its flights are dropped too.

Every other point is a phantom, with its reason: 'isolated' (its track is shorter than one window),
'not_ballistic' (no ballistic window near it), 'short_flight' (in flight, but too briefly) or 'no_rally'
(a flight in a session whose flights are all shorter than a rally's).

Measured on the tiny run (config/test/tiny.yaml, 4622 3D balls of 5996 frames, all within 2.2 cm of the
twin's truth): 15 dropped, 3 seen in one frame alone and the 12 frames of a ball falling to the floor
after a rally. Ball-free renders of its twin with an orange 40 mm marker 12 cm over a player's nose (the
issue's "3D balls at head height": 1000 3D points in 1000 frames) or wrist (3050 in 5996): none kept.
"""

from dataclasses import dataclass

import numpy as np
import pandas as pd
from numpy.lib.stride_tricks import sliding_window_view

from pingpong.common.config import Settings
from pingpong.frames import GRAVITY

REASONS = ("isolated", "not_ballistic", "short_flight", "no_rally")  # why a point is no ball (docstring)
_G = np.array([0.0, 0.0, -GRAVITY])


@dataclass(frozen=True)
class FlightRule(Settings):
    """Thresholds of the flight test (config perception.ball_flight; the module docstring says how)."""

    max_speed: float  # m/s, a linked step's speed bound (above a smash)
    link_margin: float  # m, added to a linked step's bound (measurement noise)
    max_gap_frames: int  # unseen frames a track may skip
    window_frames: int  # points in a fitted window
    max_residual_m: float  # m, RMS of a window's quadratic fit
    accel_tol: float  # m/s^2, the acceleration's fit noise allowed beside gravity and aerodynamics
    drag_per_m: float  # 1/m, the largest drag deceleration / |v|^2 (k_D)
    lift_per_m: float  # 1/m, the largest lift (Magnus) acceleration / |v|^2
    min_speed: float  # m/s, a ballistic window's least speed (at its middle): a ball in play moves
    event_frames: int  # track points a bounce or hit may leave outside every ballistic window
    min_flight_frames: int  # the fewest consecutive points of a track in flight that make a flight
    rally_frames: int  # a session whose longest flight is shorter has no ball

    def __post_init__(self):
        if self.window_frames < 4:  # a quadratic through 3 points fits anything: no residual to test
            raise ValueError(f"ball_flight.window_frames must be >= 4, got {self.window_frames}")


def link_tracks(t_s: np.ndarray, xyz: np.ndarray, rule: FlightRule, frame_s: float) -> np.ndarray:
    """Track id (N,) of every frame's point (t_s (N,) s in time order, xyz (N, 3) m, NaN unseen); -1 unseen.

    A seen point continues the open track whose last point is nearest, among those at most
    rule.max_gap_frames frames (of frame_s s) before it from which the step is one a ball can make; else it
    starts a track. So a phantom between two of the ball's points starts a track of its own and the ball's
    track goes on past it."""
    track = np.full(len(xyz), -1)
    n_tracks = 0
    open_ends: list[int] = []  # the last point of each track that may still continue
    for j in np.flatnonzero(np.isfinite(xyz).all(axis=1)):
        open_ends = [k for k in open_ends if t_s[j] - t_s[k] <= (rule.max_gap_frames + 1.5) * frame_s]
        step = [np.linalg.norm(xyz[j] - xyz[k]) for k in open_ends]
        fits = [(d, n) for n, (k, d) in enumerate(zip(open_ends, step, strict=True))
                if d <= rule.max_speed * (t_s[j] - t_s[k]) + rule.link_margin]
        if fits:
            n = min(fits)[1]
            track[j] = track[open_ends[n]]
            open_ends[n] = j
        else:
            track[j], n_tracks = n_tracks, n_tracks + 1
            open_ends.append(j)
    return track


def _window_fits(t_s: np.ndarray, xyz: np.ndarray, width: int) -> tuple[np.ndarray, ...]:
    """Quadratic fits of every run of `width` consecutive points of one track (t_s (n,), xyz (n, 3)):
    acceleration (W, 3) m/s^2, velocity at the window's middle time (W, 3) m/s and RMS residual (W,) m."""
    tw = sliding_window_view(t_s, width)  # (W, width)
    pw = sliding_window_view(xyz, width, axis=0)  # (W, 3, width)
    tc = tw - tw.mean(axis=1, keepdims=True)  # centred: a well-conditioned design
    design = np.stack([np.ones_like(tc), tc, tc**2], axis=-1)  # (W, width, 3)
    coef = np.linalg.pinv(design) @ np.swapaxes(pw, 1, 2)  # (W, 3 terms, 3 axes)
    residual = design @ coef - np.swapaxes(pw, 1, 2)
    rms = np.sqrt(np.mean(np.sum(residual**2, axis=-1), axis=-1))
    return 2 * coef[:, 2], coef[:, 1], rms


def ballistic_windows(t_s: np.ndarray, xyz: np.ndarray, rule: FlightRule) -> np.ndarray:
    """Which runs of rule.window_frames consecutive points of one track (W = n - width + 1,) are flights."""
    accel, velocity, rms = _window_fits(t_s, xyz, rule.window_frames)
    speed2 = np.sum(velocity**2, axis=1)
    heading = velocity / np.sqrt(np.maximum(speed2, 1e-12))[:, None]
    air = accel - _G  # what the air did: drag along -heading, lift across it
    drag = -np.sum(air * heading, axis=1)
    lift = np.linalg.norm(air + drag[:, None] * heading, axis=1)
    # how far the air's acceleration lies outside what drag and lift can give at this speed
    excess = np.hypot(np.maximum(drag - rule.drag_per_m * speed2, 0) + np.maximum(-drag, 0),
                      np.maximum(lift - rule.lift_per_m * speed2, 0))
    return (rms <= rule.max_residual_m) & (excess <= rule.accel_tol) & (speed2 >= rule.min_speed**2)


def _track_in_flight(t_s: np.ndarray, xyz: np.ndarray, rule: FlightRule) -> np.ndarray:
    """Which points (n,) of one track lie in, or within rule.event_frames points of, a ballistic window."""
    width = rule.window_frames
    good = ballistic_windows(t_s, xyz, rule).astype(int)
    # point i lies in windows i - width + 1 .. i; with event_frames E either side, windows
    # i - width + 1 - E .. i + E: a full convolution's entry i + E sums exactly those
    e = rule.event_frames
    covered = np.convolve(good, np.ones(width + 2 * e, int))[e:e + len(t_s)]
    return covered > 0


def _track_reasons(in_flight: np.ndarray, min_flight_frames: int) -> tuple[np.ndarray, int]:
    """(per point of one track: '' in a run of at least min_flight_frames points in flight, 'short_flight'
    in a shorter run, 'not_ballistic' out of flight; the longest run in flight)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], in_flight.astype(np.int8), [0]])))
    reasons = np.where(in_flight, "", REASONS[1]).astype(object)
    lengths = edges[1::2] - edges[::2]
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        if stop - start < min_flight_frames:
            reasons[start:stop] = REASONS[2]
    return reasons, int(lengths.max(initial=0))


def phantom_reasons(t_s: np.ndarray, xyz: np.ndarray, rule: FlightRule) -> np.ndarray:
    """Per frame (N,) '' where the point is a ball in flight or unseen, else its reason (REASONS).

    t_s: every camera frame's time (N,) s, increasing (the median step is the frame interval); xyz: the
    triangulated ball (N, 3) m, NaN where unseen."""
    t_s, xyz = np.asarray(t_s, float), np.asarray(xyz, float)
    if np.any(np.diff(t_s) <= 0):
        raise ValueError("ball frames must be in increasing time order, one row per frame")
    frame_s = float(np.median(np.diff(t_s))) if len(t_s) > 1 else 1.0
    track = link_tracks(t_s, xyz, rule, frame_s)
    reasons = np.where(track >= 0, REASONS[0], "").astype(object)
    seen = np.flatnonzero(track >= 0)
    longest = 0
    for idx in np.split(seen[np.argsort(track[seen], kind="stable")],
                        np.cumsum(np.bincount(track[seen]))[:-1]):  # each track's points in time order
        if len(idx) >= rule.window_frames:
            in_flight = _track_in_flight(t_s[idx], xyz[idx], rule)
            reasons[idx], run = _track_reasons(in_flight, rule.min_flight_frames)
            longest = max(longest, run)
    if longest < rule.rally_frames:
        reasons[seen[reasons[seen] == ""]] = REASONS[3]
    return reasons


def drop_phantoms(ball3d: pd.DataFrame, rule: FlightRule) -> tuple[pd.DataFrame, dict[str, int]]:
    """(ball3d with every phantom unseen: x, y, z and reproj_rms_px NaN, n_views 0; the count of points
    kept as 'in_flight' and dropped per reason). ball3d: one row per camera frame (BALL3D columns)."""
    time_ns = ball3d["time_ns"].to_numpy(np.int64)
    t_s = (time_ns - time_ns[:1]) * 1e-9  # from the first frame: float64 keeps the ~1e18 ns epoch exact
    reasons = phantom_reasons(t_s, ball3d[["x", "y", "z"]].to_numpy(float), rule)
    out = ball3d.copy()
    dropped = reasons != ""
    out.loc[dropped, ["x", "y", "z", "reproj_rms_px"]] = np.nan
    out.loc[dropped, "n_views"] = 0
    counts = {"in_flight": int(out["x"].notna().sum())}
    return out, counts | {r: int(np.sum(reasons == r)) for r in REASONS}


def ball_verdict(counts: dict[str, int], n_frames: int) -> tuple[bool, str]:
    """(whether the session has a ball, a line saying so with the counts of drop_phantoms)."""
    phantoms = sum(counts[r] for r in REASONS)
    why = ", ".join(f"{counts[r]} {r.replace('_', ' ')}" for r in REASONS)
    if counts["in_flight"] == 0:
        return False, (f"the session has no ball: none of its {phantoms} 3D points in {n_frames} frames lies "
                       f"on a ball's flight; all dropped as phantoms ({why})")
    return True, (f"ball in flight in {counts['in_flight']} of {n_frames} frames; {phantoms} phantom 3D "
                  f"points dropped ({why})")
