"""The renderer's faster per-frame path gives the bits of the plain one it replaced.

The twin's frames are the project's data: a speed-up of render.py may not move a byte of them. The
references below are the earlier code, verbatim in its arithmetic (render.py at 5ae9637); both sides run
on the same rays, positions and shapes and must agree exactly (benchmarks/bench_twin_revisions.py
checks whole sessions' JPEG bytes against a git revision).
"""

import numpy as np
import pytest

from pingpong.common.seeding import rng_for
from pingpong.frames import BALL_RADIUS, NET_HEIGHT, NET_OVERHANG, TABLE_HALF_LENGTH, TABLE_HALF_WIDTH
from pingpong.twin import render
from pingpong.twin.rig import make_rig


def reference_ball_layer(background, camera, positions):
    """render._ball_layer as it was: (N, K) rays by exposure samples, every occlusion test on every frame."""
    centres = positions @ camera.R.T + camera.t
    if (centres[:, 2] <= BALL_RADIUS + render.MIN_DEPTH).any():
        return None
    px = camera.project(positions)
    reach = camera.K[0, 0] * BALL_RADIUS / centres[:, 2] * 1.3 + 1.5
    x0, y0 = np.floor((px - reach[:, None]).min(axis=0)).astype(int)
    x1, y1 = np.ceil((px + reach[:, None]).max(axis=0)).astype(int) + 1
    if x1 <= 0 or y1 <= 0 or x0 >= camera.width or y0 >= camera.height:
        return None
    w, h = x1 - x0, y1 - y0
    rays = render.subpixel_rays(background.ray_map, x0, y0, w, h, render.BALL_SS).reshape(-1, 2)
    d = np.concatenate([rays, np.ones((len(rays), 1))], axis=1)
    dd = (d * d).sum(axis=1)[:, None]
    dc = d @ centres.T
    disc = dc**2 - dd * ((centres**2).sum(axis=1) - BALL_RADIUS**2)
    light = camera.R @ render.LIGHT_DIR
    d_light, d_world = d @ light, d @ camera.R
    hit = disc >= 0
    rows = np.flatnonzero(hit.any(axis=1))
    dd, dc, disc, hit = dd[rows], dc[rows], disc[rows], hit[rows]
    d_light, d_world = d_light[rows], d_world[rows]
    s = (dc - np.sqrt(np.maximum(disc, 0.0))) / dd
    n_dot_l = (s * d_light[:, None] - centres @ light) / BALL_RADIUS
    shade = render.BALL_AMBIENT + render.BALL_DIFFUSE * np.clip(n_dot_l, 0, None)
    o = camera.center
    with np.errstate(divide="ignore", invalid="ignore"):
        s_top = -o[2] / d_world[:, 2]
        s_net = -o[1] / d_world[:, 1]
    p_top = o[:2] + s_top[:, None] * d_world[:, :2]
    p_net = o[[0, 2]] + s_net[:, None] * d_world[:, [0, 2]]
    on_top = (s_top > 0) & (np.abs(p_top[:, 0]) <= TABLE_HALF_WIDTH) \
        & (np.abs(p_top[:, 1]) <= TABLE_HALF_LENGTH)
    on_net = (s_net > 0) & (np.abs(p_net[:, 0]) <= TABLE_HALF_WIDTH + NET_OVERHANG) & (p_net[:, 1] >= 0) \
        & (p_net[:, 1] <= NET_HEIGHT)
    net_pass = np.where(p_net[:, 1] >= NET_HEIGHT - render.NET_TAPE, 0.0, render.NET_TRANSMISSION)[:, None]
    coverage = hit * np.where(on_top[:, None] & (s_top[:, None] < s), 0.0, 1.0) \
        * np.where(on_net[:, None] & (s_net[:, None] < s), net_pass, 1.0)
    k = len(positions)
    fine = (h * render.BALL_SS, w * render.BALL_SS, 1)
    coverage_sum, shade_sum = np.zeros(len(d)), np.zeros(len(d))
    coverage_sum[rows], shade_sum[rows] = coverage.sum(axis=1), (coverage * shade).sum(axis=1)
    alpha = render.average_subsamples(coverage_sum.reshape(fine) / k, render.BALL_SS)
    shaded = render.average_subsamples(shade_sum.reshape(fine) / k, render.BALL_SS)
    return x0, y0, (shaded * render.BALL_BGR).astype(np.float32), alpha[..., 0].astype(np.float32), \
        hit.sum() / (k * render.BALL_SS**2)


@pytest.fixture(scope="module")
def rig_rays():
    cameras = make_rig(rng_for(3, "rig"), 4, 480, 360)
    return [(c, render.Background(None, render.pixel_ray_map(c), None, None, None, None)) for c in cameras]


def exposures(rng, n):
    """n blurred balls (5 positions over 4 ms): over the table, at the net, below the top's plane, and
    anywhere about the court (partly outside an image too)."""
    start = np.column_stack([rng.uniform(-1.2, 1.2, n), rng.uniform(-2.5, 2.5, n), rng.uniform(-0.3, 0.8, n)])
    start[: n // 4, 1] = rng.uniform(-0.06, 0.06, n // 4)  # straddling the net
    start[n // 4: n // 2, 2] = rng.uniform(-0.05, 0.05, n // 4)  # at the table top's plane
    velocity = rng.uniform(-12, 12, (n, 3))
    return start[:, None] + velocity[:, None] * np.linspace(-0.002, 0.002, 5)[None, :, None]


def test_ball_layer_equals_the_plain_one_bit_for_bit(rig_rays):
    rng = np.random.default_rng(11)
    compared = hidden = 0
    for camera, background in rig_rays:
        for positions in exposures(rng, 300):
            new, old = render._ball_layer(background, camera, positions), reference_ball_layer(
                background, camera, positions)
            assert (new is None) == (old is None)
            if new is None:
                continue
            assert new[:2] == old[:2] and new[4] == old[4]
            for a, b in zip(new[2:4], old[2:4], strict=True):
                assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
            compared += 1
            hidden += bool(new[3].sum() < new[4] * 0.999)  # by the net, the table or the image's edge
    assert compared > 600 and hidden > 50  # the occlusion tests were exercised, not only skipped


def reference_append_shapes(frames, valid, depth, kind, px, radius, size, colours):
    """render._append_shapes as it was: shape by shape, indexing nested lists and arrays by numpy integers."""
    lo = np.floor(px.min(axis=2) - radius[..., None] - 1)
    hi = np.ceil(px.max(axis=2) + radius[..., None] + 2)
    depth, size, bounds = depth.tolist(), size.tolist(), np.concatenate([lo, hi], axis=2).astype(int).tolist()
    points = render._fixed_point(px)
    for i, j in zip(*np.nonzero(valid), strict=True):
        frames[i].append(render._Shape(depth[i][j], kind, points[i, j], size[i][j], colours[i][j],
                                       tuple(bounds[i][j])))


def test_frame_shapes_equal_those_built_shape_by_shape(rig_rays, monkeypatch):
    """People and paddles of a simulated rally: every shape's fields, points and types as before."""
    from pingpong.twin.cameras import _paddles_at, frame_times
    from pingpong.twin.session import FaultRates, simulate_session
    from pingpong.twin.truth import JOINT_COLUMNS

    truth = simulate_session(1, FaultRates(), rng_for(3, "session"))
    bodies = [rows[list(JOINT_COLUMNS)].to_numpy().reshape(-1, 25, 3)[:300]
              for _, rows in truth.people.groupby("person", sort=False)]
    looks = render.make_player_looks(np.random.default_rng(0), len(bodies))
    paddles = list(_paddles_at(truth.paddles, frame_times(truth.people)[:300]).values())
    camera = rig_rays[0][0]
    new = render.frame_shapes(camera, bodies, looks, paddles)
    monkeypatch.setattr(render, "_append_shapes", reference_append_shapes)
    old = render.frame_shapes(camera, bodies, looks, paddles)
    assert sum(map(len, new)) > 3000
    for a_frame, b_frame in zip(new, old, strict=True):
        assert len(a_frame) == len(b_frame)
        for a, b in zip(a_frame, b_frame, strict=True):
            assert (a.depth, a.kind, a.size, a.colour, a.bbox) == (b.depth, b.kind, b.size, b.colour, b.bbox)
            assert type(a.size) is type(b.size) and type(a.depth) is type(b.depth)
            assert a.points.dtype == b.points.dtype and a.points.flags.c_contiguous \
                and a.points.tobytes() == b.points.tobytes()
