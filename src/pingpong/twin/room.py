"""A club room without green screens (issue 49): what makes the twin's images hard for a ball detector.

Config `twin.room` (config/schema.yaml), every feature off by default; config/config.yaml (the default
run) turns all on, config/green_screen.yaml (the paper's lab) off. Off, the twin's bytes are those
without this module (twin.render draws nothing extra, calls no rng).
Each feature copies something seen in issue 49's real club clip (static camera, 1280x720, 30 fps,
orange ball, no green screens), where the colour detector found 33 % of the free balls and 47 % of its
detections were not a ball; colours are OpenCV HSV against the detector's window H 8-19, S >= 170,
V >= 110 (twin.render's docstring):

- `wood`: a wooden box behind each table end on the floor, H 13, S 178, its lit top V 150 and its sides
  V 112 (render shades sides 0.75): the clip's brown box under a far table sat right at the brightness
  floor; a gain drift of a few per cent moves its sides across V 110 and back.
- `sign`: a banner on each end wall (white, 2.4 m x 0.8 m) printed with five ball-orange dots of 12 cm,
  ball-sized in the image from the other end (2-3 px radius at 11-12 m, the ball in play's 2-4 px at
  3-6 m): a club's sponsor banner; inside the colour window, round, still.
- `orange_clothing`: the bystander (twin.players.bystander_joints, present twin.bystander_rate of the
  time) wears an orange shirt, H 14, S 185, V 175: inside the window near its S floor, body-sized,
  moving slowly with the bystander's sway.
- `second_ball`: the share of rallies in which the server holds a second ball (the ball in play's colour
  and size, rendered by the same ray-sphere code) in the free hand from the rally's first ball sample to
  its last: in the clip the server held one "most of the time". The free hand is the wrist farther from
  the player's paddle over the rally; the ball sits beyond the hand disc's centre by its radius (held
  in the fingers: about half of it shows past the palm), so it moves with the wrist and blurs when the
  arm swings.
- `floor_balls`: balls resting on the floor around the court (behind the table ends, 1.7-5 m from the
  net); `rolling_ball`: one more rolling on the floor at 0.1-0.3 m/s (a ball rolling away after a
  rally), reflected at the court's surrounds, never stopping (chosen: the twin has no rolling friction).
- `table_balls`: balls resting on the table top, each at a place drawn once per session (uniform over the
  top 5 cm inside its edges and 15 cm or more from the net): a club leaves balls on the tables between
  rallies and drills (issue 49 asks for balls "rolling or resting on the table and floor"); ball-coloured,
  ball-sized and still, like the ball in play at a bounce, on the table where it flies.
- `gain_drift`: the camera's gain drifts slowly, 1 + a (0.6 sin(2 pi t / P1) + 0.4 sin(2 pi t / P2))
  with P1 in 40-90 s and P2 in 8-20 s (an auto-exposure following players in front of bright walls,
  daylight through windows); the amplitude a is chosen (config/config.yaml: 0.08), not measured.
- `flicker`: lamps on AC mains flicker at twice the mains frequency (IEEE Std 1789-2015; Lehman et al.
  2011, "Proposing measures of flicker in the low frequencies for lighting applications"): light
  1 + m cos(2 pi 2 f_mains t + phi), m the lamps' percent flicker / 100 (config/config.yaml: 0.10,
  chosen: electronic ballasts and good LED drivers stay below, magnetically ballasted fluorescents
  well above). Integrated over the 4 ms shutter the frame's gain is 1 + m sinc(2 f_mains T) cos(...)
  (sinc 0.76 at 100 Hz). At 100 frames/s, 120 Hz flicker (60 Hz mains) beats at 20 Hz, changing
  brightness from frame to frame; 100 Hz flicker (50 Hz mains) aliases to a constant, so
  config/config.yaml uses 60 Hz. The flicker's phase is the room's (one per session), the drift
  each camera's.

Truth: the ball in play stays alone in raw/twin_truth/{session}/{cam}_ball2d.parquet (a distractor that
hides it lowers its visibility there); the other balls' truth goes to {cam}_other_balls2d.parquet
(twin.truth.OTHER_BALLS2D: per frame and ball, named held / rolling / floor{k} / table{k}, its
mid-exposure centre x, y, z in the table frame and what a perfect detector would report of it), written
only with a ball feature on. The static distractors' truth is their geometry (room_lab's Box and Poster).

Per-frame cost: the balls at rest (floor, table) are drawn into the camera's backgrounds once
(twin.render.with_still_balls) and again only in a frame where something overlaps them, the frames of
drawing them every frame bit for bit; the moving ones (held, rolling) are ray-sphere layers like the ball
in play's, from their middle exposure sample where their image moves less than twin.cameras.BLUR_MIN_PX
over the exposure; the static distractors are in the cached background; the gain is one
cv2.convertScaleAbs over the image. CPU time of rendering + JPEG a frame at 480x360, 600 frames, median of
5 alternating runs on the shared 2-core machine (PYTHONPATH=src python benchmarks/bench_twin_room.py
--repeats 5 --camera C), room off / every feature of config/config.yaml's room on: camera 0 2.41 / 3.15 ms
(+0.74), camera 2 2.20 / 2.78 ms (+0.59); before (each ball ray cast every frame, a LUT for the gain, no
table ball) camera 0 2.56 / 4.29 (+1.73), camera 2 1.96 / 3.05 (+1.09). What is left: the held ball's
five-sample ray cast (55 % of its frames) and the rolling ball's one-sample one, 0.2-0.3 ms each a frame,
and the gain, 0.08 ms; ray casting a chunk of frames' one-sample balls in arrays at once cost more (0.44
ms a ball: every ray of a box through every step, where _ball_layer shades only the rays that hit).
Same look: the still balls' pixels and truth are those of drawing them every frame, bit for bit; with the
one-sample rule and the gain's rounding, frames before JPEG differ in 1.4e-5 of their values (camera 0,
1,494 frames; twin.cameras.BLUR_MIN_PX says how).
Failure modes: a held ball's hand whose elbow or wrist is NaN holds nothing that frame; the rolling ball
passes under the table, where only the table top hides it (the legs do not); the ball in play flies
through a table ball (the twin's balls do not meet).
"""

from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import NamedTuple

import numpy as np
import pandas as pd

from pingpong.frames import BALL_RADIUS, TABLE_HALF_LENGTH, TABLE_HALF_WIDTH
from pingpong.twin.render import HAND_RADIUS, HANDS, ROOM, Box, Lab, PlayerLook, Poster, hsv_to_bgr
from pingpong.twin.rig import FLOOR_Z

WOOD_HSV = (13, 178, 150)
SIGN_HSV = (0, 0, 225)
SIGN_MARK_HSV = (12, 220, 220)  # printed ball-orange
SIGN_MARK_RADIUS = 0.06  # m
ORANGE_SHIRT_HSV = (14, 185, 175)
COURT_HALF = (3.2, 5.5)  # x, y of the court surrounds (twin.render.make_lab's barriers), m
TABLE_BALL_MARGIN = 0.05  # m: a table ball's centre this far inside the top's edges (all of it on the top)
NET_CLEARANCE = 0.15  # m: and this far from the net's plane (clear of the net and its posts' clamps)


@dataclass(frozen=True)
class Room:
    """The room's features (config twin.room; the module docstring says what each is)."""

    wood: bool = False
    sign: bool = False
    orange_clothing: bool = False
    second_ball: float = 0.0
    floor_balls: int = 0
    rolling_ball: bool = False
    table_balls: int = 0
    gain_drift: float = 0.0
    flicker: float = 0.0
    mains_hz: float = 50.0

    @classmethod
    def from_config(cls, config: Mapping | None) -> "Room":
        return cls(**{f.name: config[f.name] for f in fields(cls) if f.name in (config or {})})

    @property
    def balls(self) -> bool:
        """Whether there are balls other than the one in play (and so their truth table)."""
        return self.second_ball > 0 or self.floor_balls > 0 or self.rolling_ball or self.table_balls > 0

    @property
    def exposure(self) -> bool:
        return self.gain_drift > 0 or self.flicker > 0


NO_ROOM = Room()  # every feature off: the plain twin


# ----------------------------------------------------------------------------------- static things

def room_lab(lab: Lab, room: Room, rng: np.random.Generator) -> Lab:
    """The lab with the room's static distractors added (the same lab when none is on)."""
    boxes, posters = list(lab.boxes), list(lab.posters)
    for end in (-1, 1):  # draws in a fixed order whatever is on: a feature's place is the same alone or not
        x = rng.choice([-1, 1]) * rng.uniform(1.6, 2.6)
        y = end * rng.uniform(4.0, 4.9)
        sign_x = rng.uniform(-1.5, 1.5)
        if room.wood:
            boxes.append(Box((x - 0.3, y - 0.22, FLOOR_Z), (x + 0.3, y + 0.22, FLOOR_Z + 0.5), WOOD_HSV))
        if room.sign:
            marks = tuple((sign_x + dx, 0.0, SIGN_MARK_RADIUS) for dx in np.linspace(-0.9, 0.9, 5))
            posters.append(Poster(end * ROOM[1, 1], (sign_x - 1.2, -0.4), (sign_x + 1.2, 0.4), SIGN_HSV,
                                  marks, SIGN_MARK_HSV))
    return replace(lab, boxes=tuple(boxes), posters=tuple(posters))


def dress_bystander(looks: list[PlayerLook], room: Room) -> list[PlayerLook]:
    """The looks with the bystander's (the last) shirt orange when `orange_clothing` is on."""
    if not room.orange_clothing:
        return looks
    shirt = tuple(float(c) for c in hsv_to_bgr(*ORANGE_SHIRT_HSV))
    return looks[:-1] + [replace(looks[-1], shirt=shirt)]


# ------------------------------------------------------------------------------------ other balls

def rally_servers(ball: pd.DataFrame) -> pd.DataFrame:
    """Per rally: its first and last ball sample's time_ns and the server's side (+1 near, -1 far),
    from where the ball is at the serve's toss (in the server's hitting plane, twin.session)."""
    first = ball.groupby("rally", sort=True).agg(start=("time_ns", "min"), end=("time_ns", "max"))
    toss_y = ball.loc[ball.groupby("rally", sort=True)["time_ns"].idxmin(), "y"].to_numpy()
    return first.assign(side=np.sign(toss_y).astype(int)).reset_index()


def free_hand_ball(joints: np.ndarray, paddle: np.ndarray) -> np.ndarray:
    """Centre (n, 3) of a ball held in the fingers of the hand farther from the paddle over these frames.

    joints: BODY_25 (n, 25, 3); paddle: positions (n, 3). The hand is twin.render's hand disc (beyond the
    wrist by 0.4 of the forearm); the ball sits beyond its centre by the hand's radius, along the forearm.
    """
    far = [np.nanmean(np.linalg.norm(joints[:, w] - paddle, axis=1)) for _, w in HANDS]
    elbow, wrist = HANDS[int(np.argmax(far))]
    forearm = joints[:, wrist] - joints[:, elbow]
    unit = forearm / np.linalg.norm(forearm, axis=1, keepdims=True)
    return joints[:, wrist] + 0.4 * forearm + HAND_RADIUS * unit


def _at_times(track: np.ndarray, frame_s: np.ndarray, sample_s: np.ndarray) -> np.ndarray:
    """A per-frame track (n, 3) linearly interpolated at sample times (n, K) (exposure samples)."""
    out = np.stack([np.interp(sample_s.ravel(), frame_s, track[:, a]) for a in range(3)], axis=1)
    return out.reshape(*sample_s.shape, 3)


def _reflect(p: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Positions on an unbounded line folded into [lo, hi] by reflection (a ball bouncing off walls)."""
    span = hi - lo
    q = np.mod(p - lo, 2 * span)
    return lo + np.where(q > span, 2 * span - q, q)


class OtherBalls(NamedTuple):
    """The balls other than the one in play, by name: moving ones' exposure positions (n, K, 3) (NaN: not
    there), still ones' resting centres (3,); table frame, m."""

    moving: dict[str, np.ndarray]
    still: dict[str, np.ndarray]


def other_ball_positions(room: Room, rng: np.random.Generator, ball: pd.DataFrame, times: np.ndarray,
                         offsets: np.ndarray, bodies: Mapping[str, np.ndarray],
                         paddles: Mapping[str, np.ndarray], sides: Mapping[int, str]) -> OtherBalls:
    """Every ball other than the one in play: held and rolling ones moving, those on the floor and the
    table still.

    times: frame times (n,) ns; offsets: exposure sample offsets (K,) ns; bodies: BODY_25 joints (n, 25, 3)
    per person at the frame times; paddles: positions (n, 3) per player; sides: side -> player name.
    rng: the session's room stream (the same for every camera: one world). The table balls come from a
    stream of their own (spawned, which draws nothing from rng): the other balls are where they were
    before table_balls existed.
    """
    frame_s = (times - times[0]) / 1e9
    sample_s = frame_s[:, None] + offsets[None] / 1e9
    moving, still = {}, {}
    table_rng = rng.spawn(1)[0]
    servers = rally_servers(ball)
    holds = rng.random(len(servers)) < room.second_ball  # drawn whatever the share: same world for any
    if room.second_ball > 0:
        held = np.full((len(times), 3), np.nan)
        for (_, rally), hold in zip(servers.iterrows(), holds, strict=True):
            if not hold:
                continue
            frames = (times >= rally["start"]) & (times <= rally["end"])
            player = sides[int(rally["side"])]
            held[frames] = free_hand_ball(bodies[player][frames], paddles[player][frames])
        moving["held"] = _at_times(held, frame_s, sample_s)
    for k in range(room.floor_balls):
        x, y = rng.uniform(-2.8, 2.8), rng.choice([-1, 1]) * rng.uniform(1.7, 5.0)
        still[f"floor{k}"] = np.array([x, y, FLOOR_Z + BALL_RADIUS])
    if room.rolling_ball:
        start = rng.uniform([-2.8, -5.0], [2.8, 5.0])
        heading = rng.uniform(0, 2 * np.pi)
        speed = rng.uniform(0.1, 0.3)
        reach = np.array(COURT_HALF) - BALL_RADIUS - 0.05  # the surrounds' boards are 4 cm thick
        x = _reflect(start[0] + speed * np.cos(heading) * sample_s, -reach[0], reach[0])
        y = _reflect(start[1] + speed * np.sin(heading) * sample_s, -reach[1], reach[1])
        moving["rolling"] = np.stack([x, y, np.full_like(x, FLOOR_Z + BALL_RADIUS)], axis=-1)
    for k in range(room.table_balls):
        x = table_rng.uniform(-1, 1) * (TABLE_HALF_WIDTH - TABLE_BALL_MARGIN)
        y = table_rng.choice([-1, 1]) * table_rng.uniform(NET_CLEARANCE,
                                                          TABLE_HALF_LENGTH - TABLE_BALL_MARGIN)
        still[f"table{k}"] = np.array([x, y, BALL_RADIUS])  # resting on the top (z = 0)
    return OtherBalls(moving, still)


# -------------------------------------------------------------------------------------- exposure

def exposure_gains(room: Room, session_rng: np.random.Generator, camera_rng: np.random.Generator,
                   times: np.ndarray, exposure_s: float) -> np.ndarray | None:
    """Per-frame gain (n,) of the image's values from the slow drift and the lamps' flicker; None when off.

    session_rng: the room's (the lamps' phase, the same for every camera); camera_rng: this camera's drift.
    """
    if not room.exposure:
        return None
    t = (times - times[0]) / 1e9
    flicker_hz = 2 * room.mains_hz
    phase = session_rng.uniform(0, 2 * np.pi)
    periods, phases = camera_rng.uniform([40.0, 8.0], [90.0, 20.0]), camera_rng.uniform(0, 2 * np.pi, 2)
    drift = room.gain_drift * (0.6 * np.sin(2 * np.pi * t / periods[0] + phases[0])
                               + 0.4 * np.sin(2 * np.pi * t / periods[1] + phases[1]))
    flicker = room.flicker * np.sinc(flicker_hz * exposure_s) * np.cos(2 * np.pi * flicker_hz * t + phase)
    return (1 + drift) * (1 + flicker)
