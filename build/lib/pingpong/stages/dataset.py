"""Rule dataset: every candidate of every session with its decision, the dataset of kept hits and the
curation table."""

import pandas as pd

from pingpong.common.artifacts import read_table, write_table
from pingpong.common.seeding import rng_for
from pingpong.curation.dataset import build_dataset, causal_input_cutoffs
from pingpong.curation.schemas import CURATION_RULES, DATASET, SEGMENTS
from pingpong.perception.schemas import BALL3D, PADDLE, POSE3D
from pingpong.reports.tables import write_report_table

CAPTION = """Every candidate hit (a segment from the ball crossing the net towards a player to that player's
strike and on through the post-hit flight) by decision: kept, or the first curation rule it failed, in
the order {rules}. Thresholds: config/schema.yaml `curation`. {kept} of {total} candidates kept;
the kept hits form processed/dataset.parquet ({n_train} train in {n_folds} folds, {n_cal} calibration,
{n_test} test, split by rally)."""


def main(ctx):
    p, i = ctx.params, ctx.input
    segments = pd.concat([read_table(f, SEGMENTS) for f in i.segments], ignore_index=True)
    paddles = [read_table(d, PADDLE) for d in i.paddle]
    sources = {"zero_phase": (i.ball, i.pose, None),
               "causal": (i.causal_ball, i.causal_pose,
                          causal_input_cutoffs(p["causal_cutoff_pose_hz"], p["causal_cutoff_ball_hz"]))}
    datasets = {}
    for kind in (p["inputs"], p["other_inputs"]):
        balls, poses, cutoffs = sources[kind]
        tables = {s: (read_table(b, BALL3D), read_table(q, POSE3D), d)
                  for s, b, q, d in zip(p["sessions"], balls, poses, paddles, strict=True)}
        # the same seed: both kinds get the same splits
        datasets[kind] = build_dataset(segments, tables, rng_for(p["seed"], "dataset"), p["n_frames"],
                                       p["test_fraction"], p["calibration_fraction"], p["n_folds"], cutoffs)
    dataset = datasets[p["inputs"]]
    prov = ctx.provenance()
    write_table(segments, ctx.output.segments, SEGMENTS, prov)
    write_table(dataset, ctx.output.dataset, DATASET, prov)
    write_table(datasets[p["other_inputs"]], ctx.output.other_inputs, DATASET, prov)
    counts = segments["decision"].value_counts().reindex(["kept", *CURATION_RULES], fill_value=0)
    table = counts.rename_axis("decision").reset_index(name="candidates")
    split = dataset["split"].value_counts()
    caption = CAPTION.format(rules=", ".join(CURATION_RULES), kept=int(counts["kept"]), total=len(segments),
                             n_train=split.get("train", 0), n_cal=split.get("calibration", 0),
                             n_test=split.get("test", 0), n_folds=p["n_folds"])
    write_report_table(table, ctx.output.md, ctx.output.csv, "Curation", caption)
