"""Rule report_twin_flights: the twin's ball flights beside the real MPI ball-gun flights."""

from pingpong.common.artifacts import read_table
from pingpong.reports.tables import write_report_table
from pingpong.reports.twin_flights import twin_flight_stats
from pingpong.twin import truth
from pingpong.twin.realdata import compare_flights_table, flight_stats, load_real_flights

CAPTION = """Median and interquartile range of flight and bounce statistics: every good shot of the
twin's sessions (its flight from the hit to the receiver, sampled at 100 Hz) beside the {real_n}
real ball-gun flights of the MPI table-tennis lab ({twin_n} twin flights). Statistics by
`pingpong.twin.realdata.flight_stats`: in/out velocities from position fits either side of the
bounce; the energy speed removes gravity so that its loss rate shows drag alone. The twin's rally
shots are faster and carry topspin, the ball gun's do not: compare the bounce ratios and angles
for the physics, the speeds for the setting."""


def main(ctx):
    twin = []
    for ball_path, shots_path in zip(ctx.input.balls, ctx.input.shots, strict=True):
        twin += twin_flight_stats(read_table(ball_path, truth.BALL), read_table(shots_path, truth.SHOTS))
    real = [flight_stats(f["times"], f["positions"], f["velocities"])
            for f in load_real_flights(ctx.input.real)]
    caption = CAPTION.format(real_n=len(real), twin_n=len(twin))
    write_report_table(compare_flights_table(twin, real), ctx.output.md, ctx.output.csv,
                       "Twin flights against real flights", caption)
