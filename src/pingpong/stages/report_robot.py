"""Rule report_robot: the paper's Tables 2-4 for every simulated controller, and the joint limits used
beside the accelerations derived from the torque limits (the paper's Table 6)."""

from pingpong.common.artifacts import read_json, read_table
from pingpong.common.seeding import rng_for
from pingpong.reports.robot import limits_table, robot_table
from pingpong.reports.tables import write_report_table
from pingpong.robot.model import ACCELERATION_SETS, read_limits, regime_robot, worst_case_accelerations
from pingpong.robot.regimes import Dynamics
from pingpong.robot.schemas import CHOICE, REGIME_CALIBRATION, SIM

CAPTION = """The simulated KUKA iiwa 14 on its Ridgeback base against every test hit's measured flight
(mirrored towards the robot), by region of the true strike point: total hits, balls hit (the ball centre
crosses y = -1.40 m within the 8 cm paddle radius of the paddle centre), hit %, and the end distance
(paddle centre to ball there) as mean and 0.5 std in cm (the paper's Tables 2-4). limit_breaches: episodes
where a position, velocity or acceleration limit was exceeded at some step. On the 'all' rows each
controller is compared with visual servoing alone on the same hits: the difference in hits, its paired
bootstrap 95 % interval ({n_boot} resamples) and the exact McNemar p-value. paper_*: the paper's Tables 2-4
for the same controller and region (223 test hits of its lab). Setting: {setting}. Controllers:
{controllers}."""

LIMITS_CAPTION = """Joint limits of the simulated robot (config/robot/limits.yaml; sources there): positions,
velocities (base m, m/s, m/s^2; arm rad, rad/s, rad/s^2), the accelerations the controller uses (the set
the configured regime's arm set: {used}; the base's from the regime's dynamics) beside both sets (table6:
the paper's Table 6; drake: Drake's iiwa14 description; base: the paper's 15 m/s^2 in both) and the torque
limits. derived_*: the acceleration
each arm joint alone can reach within the torque limits against gravity and Coriolis forces, at {n}
states sampled uniformly within the position and velocity limits (pingpong.robot.model.
worst_case_accelerations): simple = (tau_max_i - |b_i|) / M_ii, coupled = min_j (tau_max_j - |b_j|) /
|M_ji| (the other joints held), reduced by the minimum (worst case) or the median over the states.
headroom = derived_coupled_min / acceleration_used (> 1: the limit used is achievable everywhere)."""


def describe(choice: dict) -> str:
    text = f"{choice['controller']} (alpha1 {choice['alpha1']:g}, alpha2 {choice['alpha2']:g}"
    if choice["skip_centre"]:
        text += ", no anticipation on a centre prediction"
    if choice["confidence_m"] is not None:
        u_full, u_zero = choice["confidence_m"]
        text += f", alpha = 1 below {100 * u_full:.1f} cm uncertainty and 0 above {100 * u_zero:.1f} cm"
    if choice["sweep"]:
        text += f"; best of {len(choice['sweep'])} cells on {choice['n_calibration_hits']} calibration hits"
    return text + ")"


def main(ctx):
    p, i, o = ctx.params, ctx.input, ctx.output
    sims = {name: read_table(f, SIM) for name, f in zip(p["controllers"], i.sims, strict=True)}
    choices = [read_json(f, CHOICE) for f in i.choices]
    table = robot_table(sims, rng_for(p["seed"], "report_robot"), p["n_bootstrap"])
    caption = CAPTION.format(n_boot=p["n_bootstrap"], controllers="; ".join(describe(c) for c in choices),
                             setting=p["setting"])
    write_report_table(table, o.md, o.csv, "Simulated robot (Tables 2-4)", caption)
    calibration = ctx.optional_input("calibration")  # a calibrated regime's: its fitted dynamics knobs
    knobs = {} if calibration is None else read_json(calibration, REGIME_CALIBRATION).get("dynamics", {})
    dynamics = Dynamics(**{**p["dynamics"], **knobs})
    robot = regime_robot(i.urdf, i.limits, dynamics)
    derived = worst_case_accelerations(robot, rng_for(p["seed"], "robot_limits"), p["limit_samples"])
    sets = {name: read_limits(i.limits, name)["a_max"] for name in ACCELERATION_SETS}
    write_report_table(limits_table(robot, derived, sets), o.limits_md, o.limits_csv,
                       "Robot joint limits (Table 6)",
                       LIMITS_CAPTION.format(n=p["limit_samples"], used=dynamics.arm_accelerations))
