"""Rule fit_servo_ball: the visual servo's ball coefficients from the fit half of the real MPI ball-gun
flights with a published lift (pingpong.robot.servo_ball), so the servo never shares the twin's physics."""

import logging

from pingpong.common.artifacts import write_json
from pingpong.robot.schemas import SERVO_BALL
from pingpong.robot.servo_ball import describe_ball, fit_servo_ball, split_flights
from pingpong.twin.ball import BallParams
from pingpong.twin.realdata import load_real_flights

log = logging.getLogger("fit_servo_ball")


def main(ctx):
    fit_half, _ = split_flights(load_real_flights(ctx.input.real))
    fit = fit_servo_ball(fit_half)
    log.info("servo ball on %d real flights: %s (C_M, C_L_max published)", fit["n_flights"],
             describe_ball(BallParams(**fit["params"])))
    write_json(fit, ctx.output.ball, SERVO_BALL, ctx.provenance())
