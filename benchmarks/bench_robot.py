"""Speed of the robot simulation: one control step and whole episodes, against baselines in the same run.

Baselines for the step: the same control law with (a) a full Pinocchio recomputation per step
(forwardKinematics + computeJointJacobians + updateFramePlacements + getFrameJacobian, as a generic
robotics loop would do) instead of the single computeFrameJacobian call, and (b) numpy's SVD-based
pinv instead of the one 5 x 5 solve. Results are checked to agree before timing is reported.
Episodes: visual servoing alone and anticipation (alpha1 = alpha2 = 1) on simulated flights, under the
paper's timing (0.1 s steps, the default) with each servo fit, and under the fine timing (10 ms steps,
100 ms latency on top) and at 1 ms; the simulation must stay above 100 episodes per second on one core.
Regimes (config robot.regimes, the schema's defaults, with the servo's ball fitted on the real flights):
episodes per second of a first pass (servo fits included) and of a sweep's replays (goal schedules
cached, as every tuned controller replays the calibration hits), which size the regime map
(config robot.regime_map: ~70 replays per calibration hit and 6 first passes per test hit per cell).

    PYTHONPATH=src python benchmarks/bench_robot.py [--steps 3000] [--episodes 40] [--repeats 3]
"""

import argparse
import contextlib
from dataclasses import replace
from pathlib import Path
from unittest import mock

import numpy as np
import pandas as pd
import pinocchio as pin
from timing import best_time

from pingpong.common.config import schema_defaults
from pingpong.frames import STRIKE_Y
from pingpong.robot import control
from pingpong.robot.control import ControlParams, control_step
from pingpong.robot.controllers import Controller
from pingpong.robot.episode import EpisodeParams, run_episode
from pingpong.robot.evaluate import Prediction, sim_settings, simulate_hits
from pingpong.robot.flights import HitFlight
from pingpong.robot.model import load_robot, regime_robot
from pingpong.robot.regimes import parse_regime
from pingpong.robot.servo_ball import fit_servo_ball, split_flights
from pingpong.twin.ball import BallParams, aim_shots, simulate_flight, stop_at_y
from pingpong.twin.realdata import load_real_flights

ROBOT_DIR = Path(__file__).resolve().parents[1] / "config/robot"
REAL_FLIGHTS = Path(__file__).resolve().parents[1] / "data/realdata/mpi_ball_gun"
HITS = pd.DataFrame({"session": "bench", "rally": 0, "hit": np.arange(1000), "region": "centre",
                     "strike_x": 0.0, "strike_z": 0.0})


def full_recompute_jacobian(robot, q):
    """Baseline (a): everything recomputed, the frame Jacobian then read out."""
    model, data = robot.model, robot.data
    pin.forwardKinematics(model, data, q)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    jac = pin.getFrameJacobian(model, data, robot.paddle_frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    placement = data.oMf[robot.paddle_frame]
    return placement.translation, placement.rotation, jac


def pinv_resolve(task_jac, task_velocity, robot, q, params):
    """Baseline (b): the same damped, normalised pseudo-inverse through numpy's SVD pinv."""
    w = robot.v_max
    jw = task_jac * w
    pull = params.nullspace_gain * (robot.q_home - q) / w
    pull[:2] = 0.0
    lam2 = params.damping**2 + params.error_damping * (task_velocity @ task_velocity)
    jw_pinv = jw.T @ np.linalg.pinv(jw @ jw.T + lam2 * np.eye(len(jw)))
    return w * (jw_pinv @ task_velocity), w * (pull - jw_pinv @ (jw @ pull))


def run_steps(robot, n_steps, params):
    q, qd = robot.q_home.copy(), np.zeros(9)
    goals = np.array([[0.5, 0.4], [-0.4, 0.1], [0.1, 0.5]])
    path = np.empty((n_steps, 3))
    for k in range(n_steps):
        q, qd, path[k] = control_step(robot, q, qd, goals[(k // 50) % 3], 1.0, params)
    return path


def flights(n, rng):
    p_hit = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(1.5, 1.9, n), rng.uniform(0.1, 0.4, n)])
    target = np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(-1.2, -0.4, n)])
    spin = np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-30, 30, n), rng.uniform(-50, 50, n)])
    v0, _ = aim_shots(p_hit, target, spin, speed_hint=9.0)
    return [simulate_flight(p_hit[i], v0[i], spin[i], stop=stop_at_y(STRIKE_Y)) for i in range(n)]


def run_episodes(robot, tracks, params):
    out = []
    for f in tracks:
        predictions = (np.arange(-30, 1), np.tile(f.positions[-1, [0, 2]], (31, 1)))
        out.append(run_episode(robot, f.times, f.positions, predictions, params))
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    robot = load_robot(ROBOT_DIR / "iiwa14_ridgeback.urdf", ROBOT_DIR / "limits.yaml")
    params = ControlParams()

    # the variants take turns within each repeat, so a load change on the machine hits them alike
    variants = {"ours": contextlib.nullcontext(), "full": mock.patch.object(control, "paddle_jacobian",
                                                                        full_recompute_jacobian),
                "pinv": mock.patch.object(control, "resolve", pinv_resolve)}
    best, paths = dict.fromkeys(variants, np.inf), {}
    run_steps(robot, 100, params)  # warm-up
    for _ in range(args.repeats):
        for name, patch in variants.items():
            with patch:
                t, paths[name] = best_time(lambda: run_steps(robot, args.steps, params), 1)
            best[name] = min(best[name], t)
    assert np.allclose(paths["ours"], paths["full"], atol=1e-9)
    assert np.allclose(paths["ours"], paths["pinv"], atol=1e-6)
    t_ours, t_full, t_pinv = best["ours"], best["full"], best["pinv"]

    tracks = flights(args.episodes, np.random.default_rng(0))
    paper = EpisodeParams()
    fine = EpisodeParams(anticipation_period_frames=1, latency_frames=10, control=replace(params, dt=0.01))
    episode_runs = {
        "visual servoing, paper timing, model fit": paper,
        "anticipation, paper timing, model fit": replace(paper, alpha1=1.0, alpha2=1.0),
        "visual servoing, paper timing, paper fit": replace(paper, servo_fit="paper"),
        "visual servoing, fine timing (10 ms)": fine,
        "anticipation, fine timing (10 ms)": replace(fine, alpha1=1.0, alpha2=1.0),
        "anticipation, 1 ms steps": replace(fine, alpha1=1.0, alpha2=1.0, control=replace(params, dt=1e-3)),
    }
    rows = []
    for name, episode_params in episode_runs.items():
        t, out = best_time(lambda p=episode_params: run_episodes(robot, tracks, p), args.repeats)
        assert all(o["limits_ok"] for o in out)
        rows.append((name, t, np.mean([o["hit"] for o in out]), np.mean([len(o["times"]) for o in out])))

    regime_rows = regime_throughput(robot_dir=ROBOT_DIR, tracks=tracks, repeats=args.repeats)

    per_step = lambda t: t / args.steps * 1e6  # noqa: E731
    print(f"control step ({args.steps} steps, best of {args.repeats})")
    print("| variant | us / step | ratio to ours |")
    print("| --- | ---: | ---: |")
    print(f"| ours: computeFrameJacobian + one 5x5 solve | {per_step(t_ours):.1f} | 1.00 |")
    print(f"| full Pinocchio recomputation per step | {per_step(t_full):.1f} | {t_full / t_ours:.2f} |")
    print(f"| numpy SVD pinv instead of the solve | {per_step(t_pinv):.1f} | {t_pinv / t_ours:.2f} |")
    print()
    print(f"episodes ({args.episodes} flights, perfect predictions, best of {args.repeats})")
    print("| controller | episodes / s | steps / episode | hit rate | time ratio to the first |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name, t, hit_rate, steps in rows:
        print(f"| {name} | {args.episodes / t:.1f} | {steps:.0f} | {hit_rate:.2f} | {t / rows[0][1]:.2f} |")
    print()
    print(f"regimes ({args.episodes} flights, best of {args.repeats}; servo ball fitted on the real flights)")
    print("| regime | controller | episodes / s, first pass | episodes / s, sweep replay | hit rate |")
    print("| --- | --- | ---: | ---: | ---: |")
    for row in regime_rows:
        name, controller, first, replay, hit_rate = row
        print(f"| {name} | {controller} | {args.episodes / first:.1f} | {args.episodes / replay:.1f} "
              f"| {hit_rate:.2f} |")


def regime_throughput(robot_dir, tracks, repeats):
    """(regime, controller, first-pass s, replay s, hit rate) for each default regime (a calibrated one with
    example knobs: 2 cm noise, 5 frames delay) under servo and basic anticipation."""
    defaults = schema_defaults(Path(__file__).resolve().parents[1] / "config/schema.yaml")["robot"]["regimes"]
    ball = BallParams(**fit_servo_ball(split_flights(load_real_flights(REAL_FLIGHTS))[0])["params"])
    example = {"sensing": {"noise_m": 0.02, "dropout": 0.0, "delay_frames": 5}, "servo_fit": "model"}
    flights = [HitFlight(f.times, f.positions, f.times, f.positions) for f in tracks]
    predictions = [Prediction(np.arange(-30, 1), np.full(31, f.positions[-1, 0])) for f in tracks]
    rows = []
    for name, spec in defaults.items():
        regime = parse_regime(name, spec, calibration=example if spec.get("calibrated") else None)
        robot = regime_robot(robot_dir / "iiwa14_ridgeback.urdf", robot_dir / "limits.yaml", regime.dynamics)
        for controller in (Controller("servo"), Controller("anticipatory", 1.0, 1.0)):
            def run(settings, robot=robot, controller=controller):
                return simulate_hits(robot, HITS[:len(flights)], flights, predictions, controller, settings)

            first = np.inf
            for _ in range(repeats):  # a fresh cache each time: the servo fits included
                settings = sim_settings(regime, 0.15, ball)
                t, sim = best_time(lambda s=settings: run(s), 1)
                first = min(first, t)
            # replays: the schedules cached, the episodes not (a sweep's candidates move the robot apart)
            replay, _ = best_time(lambda s=settings: run(replace(s, episodes={})), repeats)
            rows.append((name, controller.name, first, replay, float(sim["hit_ball"].mean())))
    return rows


if __name__ == "__main__":
    main()
