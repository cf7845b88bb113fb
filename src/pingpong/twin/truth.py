"""Schemas of the twin's ground truth (raw/twin_truth/), which only tests and accuracy reports read."""

from pingpong.common.artifacts import Schema
from pingpong.frames import ROT_COLUMNS

JOINT_COLUMNS = tuple(f"j{k:02d}_{a}" for k in range(25) for a in "xyz")

BALL = Schema("twin_ball", 1, ("time_ns", "x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "rally", "shot"))
SHOTS = Schema("twin_shots", 2, ("rally", "shot", "hitter", "t_hit_ns", "intent", "outcome", "strike_x",
                                 "strike_z", "stroke", "deception", "pressure", "reveal_s", "late_s"))
ORACLE = Schema("twin_strike_oracle", 1, ("rally", "shot", "t_hit_ns", "frames_before_hit", "oracle_mean_x",
                                         "oracle_std_x", "oracle_q05_x", "oracle_q95_x", "oracle_n"))
EVENTS = Schema("twin_events", 1, ("time_ns", "kind", "rally", "shot", "side", "x", "y", "z"))
PEOPLE = Schema("twin_people", 1, ("time_ns", "person", *JOINT_COLUMNS))
PADDLES = Schema("twin_paddles", 1, ("time_ns", "player", "px", "py", "pz", *ROT_COLUMNS))
RIG = Schema("twin_rig", 1)
BALL2D = Schema("twin_ball2d", 1, ("time_ns", "u", "v", "visibility", "radius_px"))
# the balls other than the one in play (twin.room): per frame and ball, its mid-exposure centre (table
# frame, m) and what a perfect detector would report of it; written only when twin.room puts such balls in
OTHER_BALLS2D = Schema("twin_other_balls2d", 1, ("time_ns", "ball", "x", "y", "z", "u", "v", "visibility",
                                                 "radius_px"))
