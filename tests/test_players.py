"""Twin players: rigid skeleton, exact paddle state at the hit, plausible speeds, anticipation signal."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pingpong.frames import MODEL_JOINT_IDS, STRIKE_Y, TABLE_HALF_WIDTH
from pingpong.twin.players import BONES, FLOOR_Z, J, bystander_joints, sample_player_style
from pingpong.twin.strokes import Hit, evaluate_player, paddle_centre_at_impact, plan_player, stroke


def _unit(v):
    return v / np.linalg.norm(v)


def shot(rng, side, target_x, speed=None):
    """Stand-in for the ball physics: paddle centre, hitting normal and velocity aiming at target_x.

    Only the horizontal aim depends on the target (the rest is drawn independently of it).
    """
    ball = np.array([rng.uniform(-0.6, 0.6), side * rng.uniform(1.4, 2.0), rng.uniform(0.05, 0.4)])
    aim = _unit(np.array([target_x - ball[0], -side * abs(STRIKE_Y) - ball[1], 0.0]))
    speed = rng.uniform(3.0, 8.0) if speed is None else speed
    velocity = aim * speed + np.array([0.0, 0.0, rng.uniform(0.5, 2.0)])
    normal = _unit(aim + np.array([0.0, 0.0, rng.uniform(-0.3, 0.3)]))
    return paddle_centre_at_impact(ball, normal), normal, velocity


def rally_plans(seed, n_hits=6):
    """Both players of one rally, hits alternating 0.55-0.8 s apart, each tracking the coming ball."""
    rng = np.random.default_rng(seed)
    hits, track = {1: [], -1: []}, {1: ([], []), -1: ([], [])}
    t, side = 0.5, 1
    for _ in range(n_hits):
        target = rng.uniform(-0.7, 0.7)
        p, n, v = shot(rng, side, target)
        late = rng.uniform(-0.7, 0.7) if rng.random() < 0.3 else None
        hits[side].append(Hit(t, p, n, v, target, late))
        track[-side][0].append(t)
        track[-side][1].append(target)
        t += rng.uniform(0.55, 0.8)
        side = -side
    plans = [plan_player(s, hits[s], sample_player_style(rng), rng, *track[s]) for s in (1, -1)]
    return plans, t + 0.5, (hits[1], hits[-1])


def bone_lengths(joints):
    return np.stack([np.linalg.norm(joints[:, J[a]] - joints[:, J[b]], axis=-1) for a, b in BONES], 1)


def playing_wrist(plan, joints):
    return joints[:, J["RWrist"] if plan.style.handedness > 0 else J["LWrist"]]


def test_bones_and_paddle_grip_are_rigid_over_a_rally():
    for seed in range(3):
        plans, t_end, _ = rally_plans(seed)
        for plan in plans:
            traj = evaluate_player(plan, np.arange(0.0, t_end, 0.01))
            assert np.ptp(bone_lengths(traj.joints), axis=0).max() < 1e-3  # m
            grip = np.linalg.norm(traj.paddle_pos - playing_wrist(plan, traj.joints), axis=1)
            np.testing.assert_allclose(grip, plan.style.paddle_reach, atol=1e-9)
            assert 0.15 <= plan.style.paddle_reach <= 0.2
            rot = traj.paddle_rot
            np.testing.assert_allclose(rot.transpose(0, 2, 1) @ rot, np.broadcast_to(np.eye(3), rot.shape),
                                       atol=1e-9)
            np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-9)
            # Feet on the floor, head above the shoulders.
            assert np.all(traj.joints[:, J["RHeel"], 2] < FLOOR_Z + 0.02)
            assert np.all(traj.joints[:, J["Nose"], 2] > traj.joints[:, J["Neck"], 2])


def test_paddle_state_at_every_hit_of_a_rally():
    plans, _, hits = rally_plans(4, n_hits=8)
    dt = 1e-6
    for plan, player_hits in zip(plans, hits, strict=True):
        times = np.concatenate([h.t_hit + np.array([-dt, 0.0, dt]) for h in player_hits])
        traj = evaluate_player(plan, times)
        for i, hit in enumerate(player_hits):
            face = 1.0 if traj.forehand[i] else -1.0
            np.testing.assert_allclose(traj.paddle_pos[3 * i + 1], hit.paddle_pos, atol=1e-9)
            np.testing.assert_allclose(face * traj.paddle_rot[3 * i + 1][:, 2], _unit(hit.normal), atol=1e-9)
            np.testing.assert_allclose((traj.paddle_pos[3 * i + 2] - traj.paddle_pos[3 * i]) / (2 * dt),
                                       hit.velocity, atol=1e-3)


def _check_hit(side, p, n, v, target, late, style_seed, seed):
    style = sample_player_style(np.random.default_rng(style_seed))
    hit = Hit(0.3, p, n, v, target, late)
    plan = plan_player(side, [hit], style, np.random.default_rng(seed))
    dt = 1e-6
    traj = evaluate_player(plan, 0.3 + np.array([-dt, 0.0, dt]))
    face = 1.0 if traj.forehand[0] else -1.0
    np.testing.assert_allclose(traj.paddle_pos[1], p, atol=1e-9)  # m
    np.testing.assert_allclose(face * traj.paddle_rot[1][:, 2], _unit(n), atol=1e-9)
    # Central difference; the acceleration jumps at the hit, so the error is O(dt * jump) ~ 1e-4 m/s.
    np.testing.assert_allclose((traj.paddle_pos[2] - traj.paddle_pos[0]) / (2 * dt), v, atol=1e-3)


def test_hit_constraints_examples():
    rng = np.random.default_rng(0)
    for i in range(20):
        side = 1 if i % 2 else -1
        target = rng.uniform(-0.7, 0.7)
        p, n, v = shot(rng, side, target)
        _check_hit(side, p, n, v, target, rng.uniform(-0.7, 0.7) if i % 3 == 0 else None, i, i + 100)


@settings(max_examples=60, deadline=None)
@given(side=st.sampled_from([-1, 1]), x=st.floats(-0.9, 0.9), depth=st.floats(1.3, 2.2),
       z=st.floats(-0.05, 0.6), aim=st.floats(-0.6, 0.6), tilt=st.floats(-0.6, 0.6),
       speed=st.floats(1.0, 12.0),
       climb=st.floats(-1.0, 3.0), target=st.floats(-0.8, 0.8), late=st.none() | st.floats(-0.8, 0.8),
       style_seed=st.integers(0, 10_000), seed=st.integers(0, 10_000))
def test_hit_constraints_hold_for_random_inputs(side, x, depth, z, aim, tilt, speed, climb, target, late,
                                                style_seed, seed):
    """Any paddle state facing the opponent, anywhere a player can reach, is met exactly."""
    forward = np.array([0.0, -side, 0.0])
    across = np.array([1.0, 0.0, 0.0])
    n = _unit(forward + np.tan(aim) * across + np.array([0.0, 0.0, tilt]))
    v = speed * _unit(forward + np.tan(aim + 0.1 * tilt) * across) + np.array([0.0, 0.0, climb])
    _check_hit(side, np.array([x, side * depth, z]), n, v, target, late, style_seed, seed)


def test_speeds_are_human():
    for seed in range(6):
        plans, t_end, _ = rally_plans(10 + seed)
        for plan in plans:
            times = np.arange(0.0, t_end, 0.01)
            traj = evaluate_player(plan, times)
            joint_speed = np.linalg.norm(np.diff(traj.joints, axis=0), axis=-1) / 0.01
            assert joint_speed.max() < 15.0  # m/s; wrists of elite players peak near 10-15
            assert np.linalg.norm(np.diff(playing_wrist(plan, traj.joints), axis=0), axis=1).max() < 0.12
            assert np.linalg.norm(np.diff(traj.joints[:, J["MidHip"]], axis=0), axis=1).max() < 0.05
            turn = np.arccos(np.clip((np.trace(traj.paddle_rot[1:].transpose(0, 2, 1) @ traj.paddle_rot[:-1],
                                               axis1=1, axis2=2) - 1) / 2, -1, 1))
            assert turn.max() < 0.6  # rad per 10 ms: < 60 rad/s


def test_same_plan_agrees_at_every_sampling_rate():
    plans, t_end, _ = rally_plans(20)
    common = np.arange(0.0, t_end, 0.05)  # on both the 100 Hz and the 240 Hz grid
    a = evaluate_player(plans[0], np.arange(len(common) * 5) * 0.01)
    b = evaluate_player(plans[0], np.arange(len(common) * 12) / 240)
    np.testing.assert_allclose(a.paddle_pos[::5], b.paddle_pos[::12], atol=1e-9)
    np.testing.assert_allclose(a.joints[::5], b.joints[::12], atol=1e-9)


def test_pose_before_the_intent_shows_does_not_depend_on_the_target():
    style = sample_player_style(np.random.default_rng(5))
    times = np.arange(-1.0, 0.01, 0.01)
    p = np.array([0.2, 1.7, 0.2])
    trajs = []
    for target in (-0.6, 0.6):
        # Only the aim differs (the ball physics would also move the paddle centre by a few mm).
        aim = _unit(np.array([target - p[0], -abs(STRIKE_Y) - p[1], 0.0]))
        n, v = _unit(aim + [0.0, 0.0, 0.1]), 6.0 * aim + [0.0, 0.0, 1.0]
        trajs.append(stroke(times, 1, 0.0, p, n, v, target, style, np.random.default_rng(2)))
    early = times < -style.intent_lead
    np.testing.assert_allclose(trajs[0].joints[early], trajs[1].joints[early], atol=1e-12)
    np.testing.assert_allclose(trajs[0].paddle_rot[early], trajs[1].paddle_rot[early], atol=1e-12)
    late_diff = np.abs(trajs[0].paddle_rot[-2] - trajs[1].paddle_rot[-2]).max()
    assert late_diff > 0.1


K_BEFORE = np.arange(0, 31)  # frames (10 ms) before the hit


def _stroke_features(n_strokes, seed, late=False):
    """Per stroke the model's inputs at each frame before the hit: 8 joints, paddle position and
    rotation, and the ball at impact (what the ball's flight tells); plus the target, the decoy target,
    and (forehand, right-handed) flags that a pose model reads off the wrist's side and the paddle hand."""
    rng = np.random.default_rng(seed)
    feats, targets, decoys, flags = [], [], [], []
    for _ in range(n_strokes):
        target, decoy = rng.uniform(-0.7, 0.7, 2)
        p, n, v = shot(rng, 1, target)
        style = sample_player_style(rng)
        hit = Hit(0.0, p, n, v, target, decoy if late else None)
        plan = plan_player(1, [hit], style, rng, [-1.0], [p[0]])
        traj = evaluate_player(plan, -0.01 * K_BEFORE)
        k = len(K_BEFORE)
        feats.append(np.concatenate([traj.joints[:, MODEL_JOINT_IDS].reshape(k, -1), traj.paddle_pos,
                                     traj.paddle_rot.reshape(k, 9), np.tile(p, (k, 1))], 1))
        targets.append(target)
        decoys.append(decoy)
        flags.append([traj.forehand[0], style.handedness > 0])
    return np.array(feats), np.array(targets), np.array(decoys), np.array(flags, float)


def _design(x, flags):
    """Features with their interactions with the stroke-type flags (a linear model per stroke type)."""
    fh, rh = flags[:, :1], flags[:, 1:]
    return np.concatenate([x, x * fh, x * rh, x * fh * rh], 1)


def _ridge(x, y, lam=1.0):
    mu, sd = x.mean(0), x.std(0) + 1e-9
    z = np.column_stack([(x - mu) / sd, np.ones(len(x))])
    w = np.linalg.solve(z.T @ z + lam * np.eye(z.shape[1]), z.T @ y)
    return lambda q: np.column_stack([(q - mu) / sd, np.ones(len(q))]) @ w


@pytest.fixture(scope="module")
def anticipation():
    x, y, _, flags = _stroke_features(700, 0)
    train = np.arange(len(y)) < 500
    models = [_ridge(_design(x[train, j], flags[train]), y[train]) for j in range(len(K_BEFORE))]
    rmse = np.array([np.sqrt(np.mean((m(_design(x[~train, j], flags[~train])) - y[~train]) ** 2))
                     for j, m in enumerate(models)])
    baseline = np.sqrt(np.mean((y[~train] - y[train].mean()) ** 2))
    return models, rmse, baseline


def test_anticipation_signal_exists_and_grows_towards_the_hit(anticipation):
    _, rmse, baseline = anticipation
    assert rmse[1] < 0.25 * baseline  # 10 ms before the hit: the target is nearly determined
    assert rmse[30] > 0.8 * baseline  # 300 ms before: hardly better than guessing the mean
    assert rmse[30] > 4 * rmse[1]
    # Roughly monotone: every 5 frames further from the hit the error does not drop by more than 1 cm.
    coarse = rmse[1::5]
    assert np.all(np.diff(coarse) > -0.01), coarse
    assert rmse[15] < 0.8 * baseline  # half-way (150 ms) there is already some information


def test_late_change_shows_in_the_last_frames(anticipation):
    models, rmse, _ = anticipation
    x, target, decoy, flags = _stroke_features(150, 1, late=True)

    def err(j, truth):
        return np.sqrt(np.mean((models[j](_design(x[:, j], flags)) - truth) ** 2))

    # 150 ms before the hit the body shows the prepared (decoy) target, 10 ms before the actual one.
    assert err(15, decoy) < 0.8 * err(15, target)
    assert err(1, target) < 0.5 * err(15, target)
    assert err(1, target) < err(1, decoy)


def test_strokes_of_one_player_too_close_are_refused():
    rng = np.random.default_rng(0)
    hits = [Hit(t, *shot(rng, 1, 0.0), 0.0) for t in (1.0, 1.15)]
    with pytest.raises(ValueError, match="overlap"):
        plan_player(1, hits, sample_player_style(rng), rng)


def test_bystander_stands_beside_the_table_and_sways_a_little():
    rng = np.random.default_rng(3)
    times = np.arange(0.0, 10.0, 0.01)
    joints = bystander_joints(times, rng)
    assert joints.shape == (len(times), 25, 3)
    assert np.all(np.abs(joints[:, :, 0]) > TABLE_HALF_WIDTH + 0.3)
    assert np.ptp(bone_lengths(joints), axis=0).max() < 1e-3
    assert np.all(np.abs(joints[:, J["RHeel"], 2] - FLOOR_Z) < 0.02)
    hip = joints[:, J["MidHip"]]
    assert 0.0 < np.ptp(hip[:, :2], axis=0).max() < 0.3
    assert np.linalg.norm(np.diff(joints, axis=0), axis=-1).max() < 0.02  # < 2 m/s
