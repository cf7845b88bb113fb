"""No ball is a result (issue 36): a 3D ball is kept only on a flight; phantoms are dropped and counted, and a
session without a ball says so (pingpong.perception.ball_flight and the triangulation stage)."""

import logging

import numpy as np
import pandas as pd
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from workflow_util import ROOT

from pingpong.common.artifacts import read_json, read_table
from pingpong.common.camera import Camera
from pingpong.common.config import schema_defaults
from pingpong.common.seeding import rng_for
from pingpong.io.camera_streams import CameraFrame
from pingpong.perception.ball_flight import FlightRule, ball_verdict, drop_phantoms, phantom_reasons
from pingpong.perception.calibration import load_cameras
from pingpong.perception.detection import BallDetector, detect_stream
from pingpong.perception.schemas import BALL3D, BALL_CANDIDATES, DETECTIONS
from pingpong.perception.triangulation import ball3d_table, reprojection_gate_px
from pingpong.stages import triangulation as triangulation_stage
from pingpong.twin import truth
from pingpong.twin.ball import simulate_flight
from pingpong.twin.cameras import record_camera
from pingpong.twin.render import make_lab, make_player_looks, render_backgrounds
from pingpong.twin.session import ball_positions_at

DEFAULTS = schema_defaults(ROOT / "config" / "schema.yaml")
RULE = FlightRule.from_config(DEFAULTS["perception"]["ball_flight"])
FRAME_S = 0.01
NOISE_M = 0.0015  # per axis: the tiny run's 3D balls lie a median 1.5 mm from the truth


def coords(lo, hi):
    return st.tuples(*[st.floats(lo, hi, allow_nan=False)] * 3).map(np.array)


def sampled(times, positions, phase, rng, noise=NOISE_M):
    """A flight on the 100 Hz camera clock, with measurement noise: (t_s, xyz)."""
    t = np.arange(phase, times[-1], FRAME_S)
    xyz = np.column_stack([np.interp(t, times, positions[:, k]) for k in range(3)])
    return t, xyz + rng.normal(0, noise, xyz.shape)


def shot(p0, v0, w0):
    """A shot from the +y end over the net (the twin's physics: drag, saturating lift, table bounces) to the
    floor, or None where it hit the net or slowed below a ball in play's speed."""
    flight = simulate_flight(p0, v0, w0, t_max=2.0)
    if any(e.kind == "net" for e in flight.events):
        return None
    if np.linalg.norm(flight.velocities, axis=1).min() < RULE.min_speed:
        return None
    return flight


@settings(max_examples=40, deadline=None)
@given(p0=st.tuples(st.floats(-0.6, 0.6), st.floats(1.3, 1.7), st.floats(0.15, 0.45)),
       speed=st.floats(4.0, 14.0), vx=st.floats(-1.5, 1.5), vz=st.floats(-0.5, 2.5), w0=coords(-400, 400),
       phase=st.floats(0, FRAME_S), seed=st.integers(0, 2**16))
def test_every_point_of_a_ballistic_flight_is_kept(p0, speed, vx, vz, w0, phase, seed):
    flight = shot(np.array(p0), np.array([vx, -speed, vz]), w0)
    assume(flight is not None)
    t, xyz = sampled(flight.times, flight.positions, phase, np.random.default_rng(seed))
    assume(len(t) >= RULE.rally_frames)
    reasons = phantom_reasons(t, xyz, RULE)
    assert (reasons == "").all(), pd.Series(reasons[reasons != ""]).value_counts().to_dict()


@settings(max_examples=40, deadline=None)
@given(share=st.floats(0.05, 1.0), seed=st.integers(0, 2**16))
def test_scattered_phantoms_are_dropped(share, seed):
    """Chance coincidences of false detections: anywhere in the lab, in any frames."""
    rng = np.random.default_rng(seed)
    n = 600
    xyz = np.full((n, 3), np.nan)
    some = rng.random(n) < share
    xyz[some] = rng.uniform([-3, -5, -0.76], [3, 5, 2.5], (some.sum(), 3))
    reasons = phantom_reasons(np.arange(n) * FRAME_S, xyz, RULE)
    assert (reasons[some] != "").all()
    assert (reasons[~some] == "").all()  # unseen frames have no reason


@settings(max_examples=30, deadline=None)
@given(p0=st.tuples(st.floats(-0.6, 0.6), st.floats(1.3, 1.7), st.floats(0.15, 0.45)),
       speed=st.floats(4.0, 14.0), w0=coords(-300, 300), share=st.floats(0.01, 0.15),
       seed=st.integers(0, 2**16))
def test_phantoms_among_a_flights_points_are_dropped_and_the_flight_kept(p0, speed, w0, share, seed):
    """Phantoms in some of a flight's frames (one 3D point a frame: the phantom replaces the ball there), far
    enough from the ball not to pass for its next position."""
    flight = shot(np.array(p0), np.array([0.3, -speed, 1.0]), w0)
    assume(flight is not None)
    rng = np.random.default_rng(seed)
    t, xyz = sampled(flight.times, flight.positions, 0.0, rng)
    assume(len(t) >= RULE.rally_frames)
    fake = rng.uniform([-3, -5, -0.76], [3, 5, 2.5], xyz.shape)
    phantom = (rng.random(len(t)) < share) & (np.linalg.norm(fake - xyz, axis=1) > 1.0)
    phantom[[0, -1]] = False  # the flight's ends are its own
    assume((~phantom).sum() >= RULE.rally_frames)  # a flight of a rally's length (else the session has none)
    observed = np.where(phantom[:, None], fake, xyz)
    reasons = phantom_reasons(t, observed, RULE)
    assert (reasons[phantom] != "").all()
    assert (reasons[~phantom] == "").mean() >= 0.98, pd.Series(reasons[~phantom]).value_counts().to_dict()


@settings(max_examples=40, deadline=None)
@given(centre=st.tuples(st.floats(-2, 2), st.floats(-4, 4), st.floats(-0.7, 1.9)), amplitude=coords(0.0, 0.5),
       omega=coords(1.0, 12.0), phi=coords(0, 6.3), max_accel=st.floats(0.0, 3.0), seed=st.integers(0, 2**16))
def test_things_that_do_not_fall_are_no_ball(centre, amplitude, omega, phi, max_accel, seed):
    """A head, a hand or an object at rest: smooth motion whose acceleration stays within 3 m/s^2, never g."""
    t = np.arange(800) * FRAME_S
    wave = amplitude * np.sin(omega * t[:, None] + phi)
    accel = np.abs(amplitude * omega**2).max()
    wave *= max_accel / accel if accel > 0 else 0.0
    xyz = np.array(centre) + wave + np.random.default_rng(seed).normal(0, NOISE_M, wave.shape)
    reasons = phantom_reasons(t, xyz, RULE)
    assert (reasons != "").all()


def test_a_bounce_and_a_hit_keep_the_points_beside_them():
    """A flight turned by the table and then by a paddle 12 frames later: no window fits across either
    contact, the points beside them are kept with the flights on either side."""
    rng = np.random.default_rng(3)
    first = simulate_flight([0.1, 1.5, 0.3], [0.2, -7.0, 1.2], [0.0, 0.0, 0.0], t_max=2.0)
    bounce = next(e for e in first.events if e.kind == "bounce")
    hit_at = bounce.time + 0.12
    k = np.searchsorted(first.times, hit_at)
    back = simulate_flight(first.positions[k], [-0.3, 8.0, 2.0], [0.0, 0.0, 0.0], t_max=1.0)
    times = np.concatenate([first.times[:k], hit_at + back.times[1:]])
    positions = np.concatenate([first.positions[:k], back.positions[1:]])
    t, xyz = sampled(times, positions, 0.004, rng)
    reasons = phantom_reasons(t, xyz, RULE)
    assert (reasons == "").all(), np.flatnonzero(reasons != "")


def test_drop_phantoms_unsees_and_counts_and_the_verdict_says_no_ball():
    t_ns = 1_767_225_600_000_000_000 + np.arange(300, dtype=np.int64) * 10_000_000
    xyz = np.full((300, 3), np.nan)
    xyz[100:200] = [0.2, 2.5, 1.6] + np.random.default_rng(0).normal(0, NOISE_M, (100, 3))  # a head
    xyz[250] = [1.0, -1.0, 0.5]  # a chance coincidence
    table = pd.DataFrame({"time_ns": t_ns, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2],
                          "n_views": np.where(np.isfinite(xyz[:, 0]), 3, 0),
                          "reproj_rms_px": np.where(np.isfinite(xyz[:, 0]), 0.2, np.nan)})
    out, counts = drop_phantoms(table, RULE)
    assert out["x"].isna().all() and out["reproj_rms_px"].isna().all() and (out["n_views"] == 0).all()
    assert list(out.columns) == list(BALL3D.columns) and (out["time_ns"] == t_ns).all()
    assert counts == {"in_flight": 0, "isolated": 1, "not_ballistic": 100, "short_flight": 0, "no_rally": 0}
    has_ball, line = ball_verdict(counts, len(out))
    assert not has_ball and "the session has no ball" in line and "100 not ballistic" in line


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="increasing time order"):
        phantom_reasons(np.array([0.0, 0.02, 0.01]), np.zeros((3, 3)), RULE)
    with pytest.raises(ValueError, match="window_frames must be >= 4"):
        FlightRule.from_config(DEFAULTS["perception"]["ball_flight"] | {"window_frames": 3})


def test_the_tiny_runs_balls_are_kept(tiny_run):
    """The tiny run's detections and candidates triangulated as the stage does, then the flight rule:
    almost every 3D ball in play is kept. A ball dying on the table (hopping or rolling within 5 cm of it
    at under 1 m/s, as the harder twin's rallies often end: 0.2-0.8 m/s at z = 2-4 cm on the tiny run of
    2026-12-04, hops a few frames apart that no window fits) is no flight and may go; so may a lone frame
    or a drop to the floor. What the rule loses in play is a few points beside a smash's bounce (14-19
    m/s)."""
    cams, _ = load_cameras(tiny_run / "interim" / "calibration" / "cameras.json")
    dets = [read_table(tiny_run / "interim" / "detections" / "s00" / f"{c.name}.parquet", DETECTIONS)
            for c in cams]
    candidates = [read_table(tiny_run / "interim" / "ball_candidates" / "s00" / f"{c.name}.parquet",
                             BALL_CANDIDATES) for c in cams]
    agreed = ball3d_table(cams, dets, reprojection_gate_px(cams, DEFAULTS["perception"]["max_reproj_share"]),
                          DEFAULTS["perception"]["min_views"], candidates,
                          DEFAULTS["perception"]["ball_pair_min_frames"])
    kept, counts = drop_phantoms(agreed, RULE)
    seen = agreed["x"].notna().to_numpy()
    dropped = seen & kept["x"].isna().to_numpy()
    assert counts["in_flight"] == seen.sum() - dropped.sum()
    ball_truth = read_table(tiny_run / "raw" / "twin_truth" / "s00" / "ball.parquet", truth.BALL)
    time_ns = agreed["time_ns"].to_numpy()
    true_xyz = ball_positions_at(ball_truth, time_ns)
    step_ns = 5_000_000  # the true speed by a central difference over 10 ms
    step_m = np.subtract(*(ball_positions_at(ball_truth, time_ns + d) for d in (step_ns, -step_ns)))
    true_speed = np.linalg.norm(step_m, axis=1) / (2 * step_ns / 1e9)
    in_play = ~((true_speed < 1.0) & (true_xyz[:, 2] < 0.05))  # NaN (between rallies) counts: no excuse
    assert (dropped & in_play).sum() <= 0.005 * seen.sum(), counts
    error = np.linalg.norm(kept[["x", "y", "z"]].to_numpy() - true_xyz, axis=1)
    assert np.nanmax(error) < 0.03  # what is kept is the ball


# ---------------------------------------------------------------- a ball-free session

FRAMES = 800  # 8 s of the tiny run's session s00


def _ball_free_detections(root, ball_on) -> tuple[list[pd.DataFrame], np.ndarray]:
    """The real detector's detections of the tiny twin's cameras rendered anew for FRAMES frames of s00
    without its ball: `ball_on` None renders no ball at all; (person, joint) an orange 40 mm marker 12 cm
    above that joint of the twin's people (a cap, say: the issue's '3D balls at head height')."""
    people = read_table(root / "raw" / "twin_truth" / "s00" / "people.parquet", truth.PEOPLE)
    times = np.unique(people["time_ns"])[:FRAMES]
    people = people[people["time_ns"].isin(times)]
    paddles = read_table(root / "raw" / "twin_truth" / "s00" / "paddles.parquet", truth.PADDLES)
    t = np.arange(times[0] - 10_000_000, times[-1] + 10_000_001, 1_000_000)  # the renderer's exposures
    if ball_on is None:  # one 'rally' that ends before the first exposure: no frame shows a ball
        ball = pd.DataFrame({"time_ns": t[:2], "x": 0.0, "y": 0.0, "z": 0.0, "rally": 0})
    else:
        rows = people[people["person"] == ball_on[0]]
        xyz = [np.interp(t, rows["time_ns"], rows[f"j{ball_on[1]:02d}_{a}"]) for a in "xyz"]
        ball = pd.DataFrame({"time_ns": t, "x": xyz[0], "y": xyz[1], "z": xyz[2] + 0.12, "rally": 0})
    seed = 20261121  # config/config.yaml's, as the tiny run
    detections = []
    for spec in read_json(root / "raw" / "twin_truth" / "rig.json", truth.RIG)["cameras"]:
        camera = Camera.from_dict(spec)
        rng = rng_for(seed, "twin_camera", "ball_free", camera.name)
        backgrounds = render_backgrounds(camera, make_lab(rng_for(seed, "twin_lab")), rng)
        looks = make_player_looks(rng_for(seed, "twin_looks", "s00"), 3)
        frames = [CameraFrame(time_ns, jpeg) for time_ns, jpeg, _ in
                  record_camera(camera, backgrounds, looks, ball, people, paddles, rng, 90)]
        detections.append(detect_stream(frames, BallDetector()))
    return detections, times


@pytest.mark.parametrize("ball_on", [("near", 0), None], ids=["orange_cap_on_a_head", "nothing_orange"])
def test_a_ball_free_session_has_a_ball_in_at_most_1_percent_of_frames_and_says_so(tiny_run, caplog, ball_on):
    detections, times = _ball_free_detections(tiny_run, ball_on)
    cams, _ = load_cameras(tiny_run / "interim" / "calibration" / "cameras.json")
    if ball_on is not None:  # the hard case: every camera sees the cap and the views agree on it
        agreed = ball3d_table(cams, detections, reprojection_gate_px(cams, 0.005), 2)
        assert agreed["x"].notna().mean() >= 0.9
        assert agreed["z"].median() > 0.6  # head height over the table
    params = {k: DEFAULTS["perception"][k] for k in ("max_reproj_share", "min_views", "ball_pair_min_frames",
                                                     "ball_flight")}
    with caplog.at_level(logging.INFO):  # the stage's ball, as its main() makes it
        ball, _ = triangulation_stage.session_ball(cams, detections, params)
    assert len(ball) == FRAMES and (ball["time_ns"] == times).all()
    assert ball["x"].notna().mean() <= 0.01
    said = [r for r in caplog.records if "the session has no ball" in r.getMessage()]
    assert said and said[0].levelno == logging.WARNING

