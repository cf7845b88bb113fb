"""Rule twin_simulate: one session's ball flights, shots, events, people and paddles, and the oracle of its
good shots (ground truth)."""

from pingpong.common.artifacts import write_table
from pingpong.common.seeding import rng_for
from pingpong.twin import truth
from pingpong.twin.oracle import session_oracle
from pingpong.twin.session import FaultRates, session_epoch_ns, simulate_session


def main(ctx):
    p = ctx.params
    session = simulate_session(p["rallies"], FaultRates(**p["fault_rates"]),
                               rng_for(p["seed"], "twin_simulate", p["session"]), p["optitrack_hz"],
                               p["session_index"], p["bystander_rate"], p["homoscedastic"],
                               p["serve_toss"])
    oracle = session_oracle(session.records, rng_for(p["seed"], "twin_oracle", p["session"]),
                            session_epoch_ns(p["session_index"]),
                            p["oracle_draws"])
    prov = ctx.provenance()
    schemas = {"ball": truth.BALL, "shots": truth.SHOTS, "events": truth.EVENTS, "people": truth.PEOPLE,
               "paddles": truth.PADDLES}
    for name, schema in schemas.items():
        write_table(getattr(session, name), ctx.output[name], schema, prov)
    write_table(oracle, ctx.output["strike_oracle"], truth.ORACLE, prov)
