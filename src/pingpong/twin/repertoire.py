"""What the twin's players decide for each shot, when they decide it, and how well they execute it.

A shot is four decisions, each made at a known time (`ShotTiming`), so that the oracle
(`pingpong.twin.oracle`) can re-draw exactly those not yet made at any frame:

1. the stroke (`choose_stroke`), when the stroke starts (>= 0.45 s before the hit, so before every
   predicted frame): from the player's mix, shaped by the incoming ball (a high ball invites a smash,
   a slow backspin ball a push or flick, a fast wide ball a block);
2. the intent (`draw_intent`) at `reveal_s` before the hit: target bounce point, speed and spin. From
   then on the body shows it (`strokes.py` blends the pose towards it). When depends on the stroke
   (a loop's direction is set early by the trunk, a block's late by the paddle angle), the player's
   deception style (telegraphs, neutral, disguises) and time pressure (a fast, wide ball leaves less
   room to disguise);
3. a late change (`draw_late`) at `late_s` before the hit: the wrist turns to another lane, at a rate
   set by the deception style, the stroke and the pressure;
4. the execution (`draw_execution`) at the contact: placement, speed and spin errors that grow with
   the difficulty of the incoming ball, the ball's own variation (`sample_ball_params`), and faults.

Stroke speeds and spins (`STROKES`) follow high-speed-camera figures of human play (module
`pingpong.reports.twin_flights` lists the sources beside the twin's measured shot statistics): pushes
~3-6 m/s with backspin, blocks ~6-9 m/s with little spin, drives and loops ~9-15 m/s with 30-100+
rev/s of topspin, smashes 14+ m/s. The ranges here are the project's choice within those figures; a
stroke's speed is the aim's hint, and the net and the arc over it (`net_height`, below) take their share:
off the paddle drives leave at a median 11.3 m/s from hints of 14-18 m/s, loops at 6.1 m/s from 10-14
(the default config's sessions s00-s03; 12 m/s and 9 m/s when every shot skimmed the net).
Bounce depth (m past the net) is drawn per stroke so that most first bounces land within
0.10-0.70 m of the net, where the paper's lab saw most of them.

Net-crossing height (`net_height`: the ball centre's height above the net's top edge, m) is drawn per
shot with the target: the aim (`session._aim`) flies the ball at least that high over the net, so a
stroke's arc is the player's choice, not the lowest path that clears the tape (the earlier twin's: every
shot crossed 5-9 cm over the net, p10-p90, where real rallies spread over ~24 cm, issue 41). Figures:
- topspin defence ("fish", from off the table against a smash or a loop kill): "the ball crosses the net
  perhaps one to three feet high [0.30-0.91 m], sometimes higher or lower", with topspin (sometimes
  sidespin), landing deep (L. Hodges, "Topspin Defense", Tip of the Week, tabletenniscoaching.com,
  2019-09-16);
- the lob: "a good lob ... can go 15 feet [4.6 m] or more in the air, has lots of topspin or sidespin,
  and lands deep on the table (some players lob lower but with more spin)" (L. Hodges, Table Tennis:
  Steps to Success, Human Kinetics 1993, Step 11 "Lobbing"). The twin's lobs are the lower, spinnier
  kind, aimed 0.8-1.2 m over the net: the rig's cameras (`twin.rig`) see ~1.8 m above the table,
  and a ball out of every view for more than the curation's flight gap (0.15 s) is a lost shot, in a
  lab as here;
- the smash answers a high ball (`SMASH_HEIGHT`; "hit a lob above eye level", L. Hodges, "Smashing
  Lobs", Tip of the Week, 2019-09-09);
- the slow, spinny loop arcs "a little higher than usual, making it go deep" (L. Hodges, "Super Spinny
  Slow Loops", tabletenniscoaching.com, 2013-02-04): loops are aimed 6-32 cm over the net.
- drives, loops, sidespin strokes, pushes, flicks, blocks and smashes: no published measurement of their
  height over the net was found (searched 2026-12-05: multi-camera studies of rally trajectories and ITTF
  analyses, whose abstracts give no heights; coaching texts; Schneider et al.'s simulations of ball
  trajectories, Int. J. Comp. Sci. Sport 2013 and Appl. Sci. 2018, model the ball, not players' choices):
  their ranges (a few cm to 15-32 cm over the tape) are the project's choice, and twin_vs_real.md's net
  section labels them so beside the twin's p10 / median / p90.

Lanes (the hitter's own frame, after the dataset's mirror: left x < 0, right x > 0 seen from the robot)
are weighted towards the right as in the paper's data (Table 2: right 45 %, centre 36 %, left 18 %).
"""

from dataclasses import dataclass

import numpy as np

from pingpong.frames import STRIKE_Y
from pingpong.twin.ball import BallParams, sample_ball_params

LANES = (-1, 0, 1)  # left, centre, right in the mirrored frame
# The average player's; each player varies around them. Good shots' strike lanes on sessions s00-s07:
# right 44-45 %, centre 33-37 %, left 19-22 % (the paper's Table 2: 45 / 36 / 18 %).
LANE_WEIGHTS = np.array([0.16, 0.37, 0.47])
REV = 2 * np.pi  # rad/s per rev/s


@dataclass(frozen=True)
class StrokeKind:
    """Distributions of one stroke type. Ranges are uniform draws; spins in rev/s."""

    speed: tuple[float, float]  # m/s, the aim's speed hint
    spin: tuple[float, float]  # rev/s
    backspin: bool  # spin axis reversed: Magnus force upwards
    tilt: tuple[float, float]  # rad, spin axis tilted from horizontal towards vertical (sidespin)
    depth: tuple[float, float]  # m past the net of the bounce target
    reveal: tuple[float, float]  # s before the hit at which the body starts to show the target
    late_factor: float  # scales the player's late-change rate
    exec_factor: float  # scales the player's placement noise
    swing_scale: float  # backswing and follow-through length relative to a drive
    twist_scale: float  # trunk rotation relative to a drive
    net_height: tuple[float, float]  # m, the ball centre's height above the net's top edge (module doc)


STROKES = {
    "drive": StrokeKind((14.0, 18.0), (25.0, 45.0), False, (0.0, 0.25), (0.80, 1.20), (0.20, 0.30),
                        1.0, 1.0, 1.0, 1.0, (0.03, 0.16)),
    "loop": StrokeKind((10.0, 14.0), (50.0, 100.0), False, (0.0, 0.35), (0.45, 0.90), (0.28, 0.40),
                       0.6, 1.1, 1.2, 1.3, (0.06, 0.32)),
    "sidespin": StrokeKind((8.0, 11.0), (35.0, 70.0), False, (0.6, 1.3), (0.40, 0.80), (0.18, 0.28),
                           1.0, 1.2, 1.1, 1.1, (0.05, 0.25)),
    "push": StrokeKind((4.0, 6.0), (15.0, 35.0), True, (0.0, 0.35), (0.30, 0.65), (0.14, 0.22),
                       0.8, 0.8, 0.5, 0.4, (0.03, 0.12)),
    "flick": StrokeKind((7.0, 10.0), (20.0, 40.0), False, (0.0, 0.4), (0.40, 0.75), (0.09, 0.15),
                        1.5, 1.2, 0.6, 0.5, (0.05, 0.20)),
    "block": StrokeKind((6.0, 9.0), (5.0, 20.0), False, (0.0, 0.3), (0.40, 0.75), (0.06, 0.12),
                        1.3, 0.9, 0.4, 0.3, (0.03, 0.12)),
    "smash": StrokeKind((15.0, 19.0), (10.0, 25.0), False, (0.0, 0.2), (0.60, 1.10), (0.24, 0.34),
                        0.3, 1.4, 1.3, 1.2, (0.03, 0.15)),
    # topspin defence and the lob (module doc: Hodges 2019, 1993): slow, high, topspin, deep; the speed hint
    # only starts the aim, the net height sets the arc (a 0.3-0.9 m crossing flies at 6-9 m/s)
    "fish": StrokeKind((7.0, 10.0), (30.0, 60.0), False, (0.0, 0.5), (0.85, 1.15), (0.20, 0.30),
                       0.5, 1.2, 1.1, 0.9, (0.30, 0.91)),
    "lob": StrokeKind((6.0, 9.0), (45.0, 80.0), False, (0.0, 0.6), (0.95, 1.20), (0.22, 0.32),
                      0.3, 1.3, 1.2, 0.8, (0.80, 1.20)),
}
STROKE_NAMES = tuple(STROKES)
# Drive-heavy, as attacking players are: the good shots' speed p90 reaches 12.5 m/s with 24 % backspin on
# the default config's sessions s00-s03 (with the net heights; 12.2-12.3 m/s, 21-27 % before them).
# Topspin defence and lobs are answers to pressure (stroke_weights), rare on easy balls.
BASE_MIX = {"drive": 0.32, "loop": 0.20, "sidespin": 0.14, "push": 0.20, "flick": 0.06, "block": 0.08,
            "smash": 0.0, "fish": 0.05, "lob": 0.025}
DECEPTION = {  # reveal time scale, late-change rate
    "telegraph": (1.3, 0.01),
    "neutral": (1.0, 0.10),
    "disguise": (0.65, 0.30),
}
DECEPTION_WEIGHTS = (0.3, 0.4, 0.3)
HOMOSCEDASTIC_LATE_RATE = 0.15  # the control twin's (and the earlier twin's) share of late changes
# m above the table at the hitting plane: higher balls invite a smash. 0.27 m when every shot skimmed the
# net; with arcs over the net (STROKES' net_height) 0.27 m made a fifth of all shots smashes (4 default
# sessions), so a smash now needs a ball well above the net's top (0.25 m over it)
SMASH_HEIGHT = 0.40


@dataclass(frozen=True)
class Tactics:
    """How one player chooses and disguises shots; drawn once per player (`sample_tactics`)."""

    mix: np.ndarray  # (len(STROKES),) base stroke weights
    lane_weights: np.ndarray  # (3,) left, centre, right
    deception: str  # a key of DECEPTION
    placement_noise: float  # m, bounce-point error on an easy ball
    consistency: float  # relative speed and spin error on an easy ball
    # The control twin (config/twin_homoscedastic.yaml): intent shown `fixed_reveal_s` and a late change
    # decided `fixed_late_s` before every hit, at HOMOSCEDASTIC_LATE_RATE, execution noise the same for
    # every ball: nothing a model can see predicts when the intent shows or how often it changes.
    homoscedastic: bool = False
    fixed_reveal_s: float = 0.3
    fixed_late_s: float = 0.12


@dataclass(frozen=True)
class ShotContext:
    """What the hitter faces: all of it is visible before the stroke starts."""

    p_hit: np.ndarray  # (3,) where the ball meets the paddle
    v_in: np.ndarray  # (3,) incoming velocity
    w_in: np.ndarray  # (3,) incoming spin
    side: int  # +1: the hitter stands at +y and plays towards -y
    serve: bool

    @property
    def pressure(self) -> float:
        """Time pressure in [0, 1]: a fast ball (4 -> 12 m/s) and a wide one (|x| 0.2 -> 0.8 m)."""
        speed = np.linalg.norm(self.v_in)
        return float(np.clip(0.6 * (speed - 4.0) / 8.0 + 0.4 * (abs(self.p_hit[0]) - 0.2) / 0.6, 0.0, 1.0))

    @property
    def backspin_in(self) -> bool:
        """The incoming ball carries backspin (its Magnus force points up)."""
        return bool(np.cross(self.w_in, self.v_in)[2] > 0)


@dataclass(frozen=True)
class ShotTiming:
    stroke: str
    reveal_s: float  # the intent is made (and starts to show) this long before the hit
    late_s: float  # the late-change decision is made this long before the hit


def sample_tactics(rng: np.random.Generator, homoscedastic: bool = False) -> Tactics:
    """A player's stroke mix, lane preference, deception style and skill (and the control's timings)."""
    base = np.array([BASE_MIX[k] for k in STROKE_NAMES])
    mix = rng.dirichlet(40 * base + 1e-9 * (base == 0))
    lanes = rng.dirichlet(60 * LANE_WEIGHTS)
    deception = str(rng.choice(list(DECEPTION), p=DECEPTION_WEIGHTS))
    return Tactics(mix, lanes, deception, float(rng.uniform(0.02, 0.05)), float(rng.uniform(0.02, 0.05)),
                   homoscedastic, float(rng.uniform(0.20, 0.40)), float(rng.uniform(0.10, 0.15)))


def stroke_weights(tactics: Tactics, ctx: ShotContext) -> np.ndarray:
    """The player's mix reshaped by the incoming ball, normalised."""
    w = dict(zip(STROKE_NAMES, tactics.mix, strict=True))
    if ctx.serve:  # a serve carries backspin or sidespin
        w = {k: (v if k in ("push", "sidespin") else 0.0) for k, v in w.items()}
    else:
        p = ctx.pressure
        if ctx.backspin_in:
            w["push"] *= 3.0
            w["flick"] *= 2.5
            w["drive"] *= 0.4
            w["block"] *= 0.2
        else:
            w["push"] *= 0.7
        w["block"] *= 1 + 4 * p
        z = ctx.p_hit[2]  # a high ball is driven flat and fast, a low one looped up
        w["drive"] *= float(np.clip((z - 0.10) / 0.12, 0.1, 2.5))
        w["loop"] *= float(np.clip((0.34 - z) / 0.12, 0.2, 1.5)) * (1 - 0.6 * p)
        w["sidespin"] *= 1 - 0.6 * p
        # played from off the table against fast balls (Hodges 2019: "against a smash or a loop kill")
        w["fish"] *= (0.2 if ctx.backspin_in else 1.0) * (0.4 + 2.0 * p)
        w["lob"] *= (0.1 if ctx.backspin_in else 1.0) * (0.2 + 2.5 * p)
        if ctx.p_hit[2] > SMASH_HEIGHT:
            w["smash"] = 3.0 * sum(w.values())
    total = np.array(list(w.values()))
    return total / total.sum()


def choose_stroke(rng: np.random.Generator, tactics: Tactics, ctx: ShotContext) -> ShotTiming:
    """Decision 1: the stroke, and when its later decisions fall."""
    name = str(rng.choice(STROKE_NAMES, p=stroke_weights(tactics, ctx)))
    if tactics.homoscedastic:
        return ShotTiming(name, tactics.fixed_reveal_s, tactics.fixed_late_s)
    kind = STROKES[name]
    scale = DECEPTION[tactics.deception][0] * (1 + 0.3 * ctx.pressure)
    reveal = float(np.clip(rng.uniform(*kind.reveal) * scale, 0.05, 0.42))
    late = float(rng.uniform(0.35, 0.6) * reveal)
    return ShotTiming(name, reveal, late)


def late_rate(tactics: Tactics, timing: ShotTiming, ctx: ShotContext) -> float:
    """Probability of a late change: the player's style, the stroke, and less under time pressure."""
    if tactics.homoscedastic:
        return HOMOSCEDASTIC_LATE_RATE
    return float(np.clip(DECEPTION[tactics.deception][1] * STROKES[timing.stroke].late_factor
                         * (1 - 0.7 * ctx.pressure), 0.0, 0.6))


def _lane_point(rng, lanes: np.ndarray, kind: StrokeKind, ctx: ShotContext) -> np.ndarray:
    """Bounce targets (n, 2) in the table frame for lanes (n,) of the mirrored frame.

    A lane is a stretch of the strike line (left, centre, right of the robot, as the paper's regions);
    the bounce target lies on the straight line from the hit to that stretch, at the stroke's depth.
    """
    n, side = len(lanes), ctx.side
    x = np.where(lanes == 0, rng.uniform(-0.22, 0.22, n), lanes * rng.uniform(0.30, 0.75, n))
    aim = np.column_stack([side * x, np.full(n, -side * abs(STRIKE_Y))])
    y = -side * rng.uniform(*kind.depth, n)
    f = (y - ctx.p_hit[1]) / (aim[:, 1] - ctx.p_hit[1])
    return np.column_stack([np.clip(ctx.p_hit[0] + f * (aim[:, 0] - ctx.p_hit[0]), -0.7, 0.7), y])


def draw_intent(rng: np.random.Generator, tactics: Tactics, timing: ShotTiming, ctx: ShotContext,
                n: int) -> dict:
    """Decision 2, n draws: lane (n,), bounce target (n, 2), speed (n,) m/s, spin (n,) rad/s, tilt (n,),
    net_height (n,) m: the ball centre's height over the net's top edge the shot is aimed at (at least)."""
    kind = STROKES[timing.stroke]
    lanes = rng.choice(np.array(LANES), size=n, p=tactics.lane_weights)
    target = _lane_point(rng, lanes, kind, ctx)
    return {"lane": lanes, "target": target, "speed": rng.uniform(*kind.speed, n),
            "spin": REV * rng.uniform(*kind.spin, n),
            "tilt": rng.uniform(*kind.tilt, n) * rng.choice([-1.0, 1.0], n),
            "net_height": rng.uniform(*kind.net_height, n)}


def draw_late(rng: np.random.Generator, tactics: Tactics, timing: ShotTiming, ctx: ShotContext,
              intent: dict) -> dict:
    """Decision 3 on draw_intent's intents: some turn to another lane (a new point there), `late` (n,)."""
    n = len(intent["lane"])
    late = rng.random(n) < late_rate(tactics, timing, ctx)
    shift = rng.choice([1, 2], size=n)  # to one of the two other lanes
    lanes = np.where(late, (intent["lane"] + 1 + shift) % 3 - 1, intent["lane"])
    fresh = _lane_point(rng, lanes, STROKES[timing.stroke], ctx)
    return {**intent, "lane": lanes, "late": late,
            "target": np.where(late[:, None], fresh, intent["target"])}


def difficulty(ctx: ShotContext) -> float:
    """How hard the incoming ball is to control, >= 0: time pressure and its spin (per 50 rev/s)."""
    return ctx.pressure + float(np.linalg.norm(ctx.w_in)) / (50 * REV)


def draw_execution(rng: np.random.Generator, tactics: Tactics, timing: ShotTiming, ctx: ShotContext,
                   n: int, ball: BallParams = BallParams()) -> dict:
    """Decision 4, at the contact, n draws: target error (n, 2) m, speed, spin factors (n,), ball params."""
    kind = STROKES[timing.stroke]
    grow = 1.0 if tactics.homoscedastic else 1 + 1.5 * difficulty(ctx)
    sigma = tactics.placement_noise * (1.0 if tactics.homoscedastic else kind.exec_factor) * grow
    rel = tactics.consistency * grow
    return {"target_error": rng.normal(0.0, sigma, (n, 2)),
            "speed_factor": np.clip(1 + rel * rng.standard_normal(n), 0.7, 1.3),
            "spin_factor": np.clip(1 + 2 * rel * rng.standard_normal(n), 0.4, 1.6),
            "params": [sample_ball_params(rng, base=ball) for _ in range(n)]}


def executed_shot(ctx: ShotContext, timing: ShotTiming, intent: dict, final: dict, execution: dict):
    """Bounce targets (n, 2), speed hints (n,), wanted spins (n, 3) and net heights (n,) m of decided shots
    (the height as intended: the execution's error shows in the bounce point, speed and spin)."""
    target = final["target"] + execution["target_error"]
    # an error towards the net leaves the ball at least 10 cm past it (nearer, no shot clears the net)
    target[:, 1] = -ctx.side * np.maximum(-ctx.side * target[:, 1], 0.10)
    speed = intent["speed"] * execution["speed_factor"]
    w = spin_vector(target, ctx.p_hit, intent["spin"] * execution["spin_factor"], intent["tilt"],
                    STROKES[timing.stroke].backspin)
    return target, speed, w, intent["net_height"]


def spin_vector(target: np.ndarray, p_hit: np.ndarray, spin: np.ndarray, tilt: np.ndarray,
                backspin: bool) -> np.ndarray:
    """Spin vectors (n, 3) rad/s: topspin (or backspin) about the horizontal axis across the travel
    from p_hit to the target, tilted by `tilt` towards the vertical (sidespin)."""
    d = np.column_stack([target - p_hit[:2], np.zeros(len(target))])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    across = np.cross(np.array([0.0, 0.0, 1.0]), d)  # w along it gives topspin: (z x d) x d = -z
    axis = np.cos(tilt)[:, None] * across + np.sin(tilt)[:, None] * np.array([0.0, 0.0, 1.0])
    return (-1.0 if backspin else 1.0) * spin[:, None] * axis


def target_strike_x(p_hit: np.ndarray, target: np.ndarray, strike_y: float) -> np.ndarray:
    """x (n,) where the straight line from the hit over the bounce target reaches y = strike_y: the
    direction a player aims the body at (the flight's own crossing differs by spin and bounce)."""
    f = (strike_y - p_hit[1]) / (target[:, 1] - p_hit[1])
    return p_hit[0] + f * (target[:, 0] - p_hit[0])
