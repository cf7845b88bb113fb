"""Rule report_twin_flights: the twin's ball flights beside the real MPI ball-gun flights, and the twin's
shot statistics beside published figures of human play."""

import pandas as pd

from pingpong.common.artifacts import read_table
from pingpong.reports.twin_flights import HIGH_OVER_NET, net_crossings, net_table, twin_flight_stats
from pingpong.reports.twin_shots import good_shot_table, shot_stats_table, write_sections
from pingpong.twin import truth
from pingpong.twin.realdata import compare_flights_table, flight_stats, load_real_flights

CAPTION = """Median and interquartile range of flight and bounce statistics: every good shot of the
twin's sessions (its flight from the hit to the receiver, sampled at 100 Hz) beside the {real_n}
real ball-gun flights of the MPI table-tennis lab ({twin_n} twin flights). Statistics by
`pingpong.twin.realdata.flight_stats`: in/out velocities from position fits either side of the
bounce; the energy speed removes gravity so that its loss rate shows drag alone. The twin's rally
shots are faster and carry topspin, the ball gun's do not: compare the bounce ratios and angles
for the physics, the speeds for the setting."""

SHOT_CAPTION = """The twin's {n} good shots (outcome 'ok', {sessions} sessions), from the shots' outgoing
velocity and spin and the first bounce of each shot in the events, beside published figures of human
play (`pingpong.reports.published_shots`; "no published figure found" where the search found none).
`twin` is the median (p50), or the share on share rows; twin_p10 and twin_p90 the 10th and 90th
percentiles. Spin types by the Magnus force F = w x v_out (`pingpong.reports.twin_shots.spin_types`):
sidespin-dominant when the horizontal part of F across the flight exceeds |F|/2, else backspin when
F_z > 0 and topspin when F_z < 0. Per-stroke rows where the shots name their strokes. The published
figures are means, ranges or records of other players and setups, not percentiles of this lab."""


NET_CAPTION = """Where the twin's {n} good shots cross the net (`pingpong.reports.twin_flights.net_crossings`,
on the 1 kHz truth flights): the ball centre's height over the net's top edge (0.1525 m over the table)
and its speed there, p10 / median / p90, overall and per stroke, and the share crossing more than
{high:.2f} m over the net; beside published figures of human play. The real ball-gun recordings
(`real_*`, {real_n} MPI flights) are in the lab's frame with no net position, so they have no
net-crossing figures: the speed before the first bounce (both measured by `flight_stats`) stands beside
them instead. No published percentiles of net-crossing heights or speeds at the net were found; issue 41
measured real rallies of recordings this project has not seen at a p10-p90 spread of ~24 cm. The twin's
stroke heights are aimed ranges (`pingpong.twin.repertoire.STROKES`, net_height) that the flight meets
or exceeds; where no published measurement gives a stroke's height, the published column says so and
labels the aimed range the project's choice (fish and lob: coaching texts' figures)."""


def main(ctx):
    twin, good, crossings = [], [], []
    for ball_path, shots_path, events_path in zip(ctx.input.balls, ctx.input.shots, ctx.input.events,
                                                  strict=True):
        shots = read_table(shots_path, truth.SHOTS)
        ball = read_table(ball_path, truth.BALL)
        twin += twin_flight_stats(ball, shots)
        crossings.append(net_crossings(ball, shots))
        good.append(good_shot_table(shots, read_table(events_path, truth.EVENTS)))
    real = [flight_stats(f["times"], f["positions"], f["velocities"])
            for f in load_real_flights(ctx.input.real)]
    good = pd.concat(good, ignore_index=True)
    crossings = pd.concat(crossings, ignore_index=True)
    write_sections(ctx.output.md, ctx.output.csv, "Twin flights and shots against real play", [
        ("flights", "Flights against the MPI ball gun", CAPTION.format(real_n=len(real), twin_n=len(twin)),
         compare_flights_table(twin, real)),
        ("shots", "Shot statistics of the twin beside published figures of human play",
         SHOT_CAPTION.format(n=len(good), sessions=len(ctx.input.shots)), shot_stats_table(good)),
        ("net", "Net-crossing height and speed at the net",
         NET_CAPTION.format(n=len(crossings), high=HIGH_OVER_NET, real_n=len(real)),
         net_table(crossings, twin, real)),
    ])
