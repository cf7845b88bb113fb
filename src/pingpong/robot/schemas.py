"""The robot stages' artifact layouts (light: no Pinocchio)."""

from pingpong.common.artifacts import Schema

SIM = Schema("robot_sim", 2, (
    "controller", "session", "rally", "hit", "region", "strike_x", "strike_z", "hit_ball", "end_distance_m",
    "anticipated", "limits_ok", "max_velocity_ratio", "max_acceleration_ratio", "min_position_margin",
    "servo_no_estimate"))
CHOICE = Schema("robot_controller", 1)  # processed/sim/{controller}.json: the settings and the sweep
# processed/robot/servo_ball.json: the servo model fit's ball coefficients, fitted on real flights
SERVO_BALL = Schema("servo_ball", 1)
# processed/robot/regime_{name}.json: a calibrated regime's sensing, servo fit and dynamics knobs, and the
# fit's table
REGIME_CALIBRATION = Schema("regime_calibration", 2)  # 2: the dynamics knobs
# processed/robot/regime_map/{cell}.json: one cell of the regime map (per-hit results of every controller)
REGIME_CELL = Schema("regime_cell", 1)
