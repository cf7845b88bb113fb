"""The robot stages' artifact layouts (light: no Pinocchio)."""

from pingpong.common.artifacts import Schema

SIM = Schema("robot_sim", 2, (
    "controller", "session", "rally", "hit", "region", "strike_x", "strike_z", "hit_ball", "end_distance_m",
    "anticipated", "limits_ok", "max_velocity_ratio", "max_acceleration_ratio", "min_position_margin",
    "servo_no_estimate"))
CHOICE = Schema("robot_controller", 1)  # processed/sim/{controller}.json: the settings and the sweep
