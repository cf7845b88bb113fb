"""Rule report_curation: events, curation decisions, filtering and labels against the twin's truth."""

import pandas as pd

from pingpong.common.artifacts import read_table
from pingpong.curation.schemas import EVENTS, SEGMENTS
from pingpong.perception.schemas import BALL3D
from pingpong.reports import curation_accuracy as acc
from pingpong.reports.tables import write_report_table
from pingpong.twin import truth
from pingpong.twin.session import ball_positions_at

CAPTION = """Curation measured against the digital twin's ground truth, pooled over every session of this
run, beside the threshold it must meet (`ok`). Events: a true hit or bounce is found when a detected event
of the same kind lies within one frame (10 ms); serves (the twin's ball appears at the serve) and bounces
falling slower than 1 m/s (a dead ball's last hops) are not required, but a detection near one is real;
a detected hit or bounce is spurious when no true one of its kind lies within a frame. Decisions: each
candidate is matched to the twin's shot whose hit is nearest, within a frame (none: not a true hit, a
disagreement); 'kept' must meet an 'ok' return, 'net'/'out'/'double_bounce' that fault, and, as in the
curation tests, an 'out' ball that bounced once on the opponent's half and fell beside the table
'no_strike_line'. Rejections for data quality (gaps, too few points) of true 'ok' returns are left out
of the agreement: {quality} of {ok} true ok returns here. Filtering: median distance of the unfiltered and
the filtered ball to the true ball at the camera frames, on frames in flight (within a rally's true
flight) where both exist. Labels: kept candidates, strike point x from a1, a2, b at y = -1.40 m against
the measured crossing, and the measured crossing against the twin's (mirrored) strike point."""


def main(ctx):
    p, i = ctx.params, ctx.input
    segments = read_table(i.segments, SEGMENTS)
    per_session, errors = [], []
    for k, session in enumerate(p["sessions"]):
        shots, events = read_table(i.shots[k], truth.SHOTS), read_table(i.events[k], truth.EVENTS)
        ball = read_table(i.ball[k], truth.BALL)
        ball3d, filtered = read_table(i.ball3d[k], BALL3D), read_table(i.filtered[k], BALL3D)
        true_xyz = ball_positions_at(ball, ball3d["time_ns"].to_numpy())
        errors.append(acc.in_flight_errors(ball3d, filtered, true_xyz))
        per_session.append((read_table(i.detected[k], EVENTS), events, shots, ball,
                            segments[segments["session"] == session]))
    decisions = acc.decision_table([(seg, shots, events) for _, events, shots, _, seg in per_session])
    rows = acc.event_rows([s[:4] for s in per_session])
    rows += acc.decision_rows(decisions)
    rows += acc.filtering_rows(errors)
    rows += acc.label_rows([(seg, shots) for _, _, shots, _, seg in per_session])
    caption = CAPTION.format(quality=int(decisions["data_quality"].sum()),
                             ok=int((decisions["expected"] == "kept").sum()))
    write_report_table(pd.DataFrame(rows), ctx.output.md, ctx.output.csv, "Curation accuracy", caption)
