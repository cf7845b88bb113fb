"""Rule oracle_uncertainty (twin only): the twin's strike oracle as an uncertainty table of the calibration
and test hits, which the oracle-driven confidence-scaled controller reads (the ceiling of confidence)."""

from pingpong.common.artifacts import read_table, write_table
from pingpong.curation.schemas import DATASET
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports.uncertainty_oracle import oracle_uncertainty, read_oracles
from pingpong.uncertainty.schemas import UNCERTAINTY


def main(ctx):
    i, sessions = ctx.input, ctx.params["sessions"]
    oracles = read_oracles(sessions, i.oracle)
    dataset, predictions = read_table(i.dataset, DATASET), read_table(i.predictions, PREDICTIONS)
    table = oracle_uncertainty(dataset, predictions, oracles)
    write_table(table[list(UNCERTAINTY.columns)], ctx.output.table, UNCERTAINTY, ctx.provenance())
