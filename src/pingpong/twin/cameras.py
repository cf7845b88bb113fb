"""One camera's recording of a session: what it saw, frame by frame, as JPEG in MCAP, plus its truth.

Truth paddle rotations follow twin.strokes (column 0 handle to tip, column 2 the forehand face
normal); the renderer's paddle frame has y from handle to tip and z out of the red (forehand)
side, so its columns are (-col1, col0, col2) of the truth's.
"""

from collections.abc import Iterator

import numpy as np
import pandas as pd

from pingpong.common.camera import Camera
from pingpong.frames import ROT_COLUMNS
from pingpong.twin.render import (
    Background,
    BallTruth,
    PlayerLook,
    encode_jpeg,
    frame_shapes,
    render_scene,
    with_still_balls,
)
from pingpong.twin.room import NO_ROOM, OtherBalls, Room, exposure_gains, other_ball_positions
from pingpong.twin.session import SIDES, ball_positions_at
from pingpong.twin.truth import JOINT_COLUMNS

EXPOSURE_NS = 4_000_000  # 4 ms shutter: the ball moves 2-5 cm in it, hence the motion blur
EXPOSURE_SAMPLES = 5
DISTRACTOR_PERIOD_NS = 20_000_000_000  # the ball bucket stands by the table every other 20 s
SHAPE_CHUNK = 256  # frames whose shapes are built at once: vectorised, in bounded memory
# a ball other than the one in play whose image travels less than this over the exposure is drawn from its
# middle exposure sample (blur below a quarter pixel averages to the middle position, to first order), its
# truth still the mean of all: twin.room's rolling ball always (0.02-0.13 px at 480x360), its held ball
# 41-47 % of its frames. Camera 0 of benchmarks/bench_twin_room.py, the room on: 0.19 ms a frame less
# (median of 4 runs of 600 frames); the frames before JPEG differ from five samples' (and a LUT's gain) in
# 1.4e-5 of their values (1-3 DN mostly, at most 14: an edge pixel's coverage steps of 1/16 with 4x4
# subsamples), the held and rolling balls' visibility by at most 0.014, their pixel, radius and centre not
# at all
BLUR_MIN_PX = 0.25


def render_paddle_rotation(truth_rot: np.ndarray) -> np.ndarray:
    """Renderer paddle axes (..., 3, 3) from the truth's (see the module docstring)."""
    return np.stack([-truth_rot[..., :, 1], truth_rot[..., :, 0], truth_rot[..., :, 2]], axis=-1)


def _paddles_at(paddles: pd.DataFrame, time_ns: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each player's paddle at the camera times: position interpolated, rotation of the nearest sample."""
    out = {}
    for player, rows in paddles.groupby("player", sort=False):
        t = rows["time_ns"].to_numpy()
        pos = np.column_stack([np.interp(time_ns, t, rows[c].to_numpy()) for c in ("px", "py", "pz")])
        nearest = np.clip(np.searchsorted(t, time_ns), 0, len(t) - 1)
        rot = rows[list(ROT_COLUMNS)].to_numpy()[nearest].reshape(-1, 3, 3)
        out[player] = (pos, render_paddle_rotation(rot))
    return out


def frame_times(people: pd.DataFrame) -> np.ndarray:
    return np.unique(people["time_ns"].to_numpy())


def record_camera(camera: Camera, backgrounds: tuple[Background, Background], looks: list[PlayerLook],
                  ball: pd.DataFrame, people: pd.DataFrame, paddles: pd.DataFrame, rng: np.random.Generator,
                  jpeg_quality: int) -> Iterator[tuple[int, bytes, dict]]:
    """(time_ns, JPEG, ball truth row) for every camera frame of the session, in time order."""
    frames = record_room_camera(camera, backgrounds, looks, ball, people, paddles, rng, jpeg_quality)
    for t, jpeg, row, _ in frames:
        yield t, jpeg, row


RoomFrame = tuple[int, bytes, dict, list]  # time_ns, JPEG, ball truth row, other balls' truth rows


def record_room_camera(camera: Camera, backgrounds: tuple[Background, Background], looks: list[PlayerLook],
                       ball: pd.DataFrame, people: pd.DataFrame, paddles: pd.DataFrame,
                       rng: np.random.Generator, jpeg_quality: int, room: Room = NO_ROOM,
                       room_rng: np.random.Generator | None = None,
                       gain_rng: np.random.Generator | None = None) -> Iterator[RoomFrame]:
    """record_camera's frames with the room's moving things (twin.room), and the other balls' truth rows.

    room_rng: the session's room stream (the same for every camera); gain_rng: this camera's drift. With
    the room's features off neither is used and the frames are record_camera's, bit for bit.
    """
    times = frame_times(people)
    offsets = np.linspace(-EXPOSURE_NS / 2, EXPOSURE_NS / 2, EXPOSURE_SAMPLES).astype(np.int64)
    exposure = ball_positions_at(ball, (times[:, None] + offsets[None]).ravel())
    exposure = exposure.reshape(len(times), EXPOSURE_SAMPLES, 3)
    bodies = {p: rows[list(JOINT_COLUMNS)].to_numpy().reshape(-1, 25, 3)
              for p, rows in people.groupby("person", sort=False)}
    pads = _paddles_at(paddles, times)
    balls_rng, lamps_rng = room_rng.spawn(2) if room_rng is not None else (None, None)
    others = other_ball_positions(room, balls_rng, ball, times, offsets, bodies,
                                  {p: pos for p, (pos, _) in pads.items()}, SIDES) if room.balls \
        else OtherBalls({}, {})
    if others.still:  # drawn into the backgrounds once, not ray cast every frame (render.StillBalls)
        backgrounds = tuple(with_still_balls(b, camera, list(others.still.values())) for b in backgrounds)
    travel = {name: _image_travel(camera, p) for name, p in others.moving.items()}
    gains = exposure_gains(room, lamps_rng, gain_rng, times, EXPOSURE_NS / 1e9)
    persons = list(SIDES.values()) + ["bystander"]
    for first in range(0, len(times), SHAPE_CHUNK):
        chunk = slice(first, first + SHAPE_CHUNK)
        shapes = frame_shapes(camera, [bodies[p][chunk] for p in persons], looks,
                              [(pads[p][0][chunk], pads[p][1][chunk]) for p in SIDES.values()])
        for i, frame in enumerate(shapes, start=first):
            yield _camera_frame(camera, backgrounds, times[i], exposure[i], frame, rng, jpeg_quality,
                                {name: (p[i], travel[name][i]) for name, p in others.moving.items()},
                                others.still, None if gains is None else float(gains[i]))


def _truth_row(t: int, truth: BallTruth) -> dict:
    return {"time_ns": int(t), "u": truth.pixel[0], "v": truth.pixel[1], "visibility": truth.visibility,
            "radius_px": truth.radius_px}


def _image_travel(camera: Camera, positions: np.ndarray) -> np.ndarray:
    """Per frame, the length (px) of the image path of exposure positions (n, K, 3); NaN where not there."""
    n, k, _ = positions.shape
    ok = np.isfinite(positions).all(axis=(1, 2))
    travel = np.full(n, np.nan)
    if ok.any():
        px = camera.project(positions[ok].reshape(-1, 3)).reshape(-1, k, 2)
        travel[ok] = np.linalg.norm(np.diff(px, axis=1), axis=2).sum(axis=1)
    return travel


def _camera_frame(camera, backgrounds, t, exposure, shapes, rng, jpeg_quality, moving, still, gain):
    present = {name: p for name, (p, _) in moving.items() if np.isfinite(p).all()}
    centres = {name: p.mean(axis=0) for name, p in present.items()}
    mid = EXPOSURE_SAMPLES // 2
    drawn = [p if moving[name][1] >= BLUR_MIN_PX else p[mid:mid + 1] for name, p in present.items()]
    balls = [exposure[np.isfinite(exposure).all(axis=1)], *drawn]
    background = backgrounds[int((t // DISTRACTOR_PERIOD_NS) % 2)]
    image, truths = render_scene(background, camera, [b if len(b) else None for b in balls], shapes, rng,
                                 gain=gain, centres=[None, *centres.values()])
    # render_scene's truths: the balls given, then the background's still balls
    other_rows = [{"time_ns": int(t), "ball": name, **dict(zip("xyz", centre.tolist(), strict=True)),
                   **_truth_row(t, truth)}
                  for (name, centre), truth in zip([*centres.items(), *still.items()], truths[1:],
                                                   strict=True)]
    return int(t), encode_jpeg(image, jpeg_quality), _truth_row(t, truths[0]), other_rows
