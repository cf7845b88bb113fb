"""Rule report_oracle_learnability: the ceiling an estimator's ranking of the twin's oracle std is read
against (pingpong.uncertainty.learnability), and each estimator's share of it."""

import numpy as np
import pandas as pd
import torch

from pingpong.common.artifacts import read_table
from pingpong.curation.schemas import DATASET, dataset_arrays
from pingpong.learning.schemas import PREDICTIONS
from pingpong.reports.tables import write_report_table
from pingpong.reports.uncertainty import ORACLE_FRAMES
from pingpong.reports.uncertainty_oracle import join_test_hits, read_oracles
from pingpong.reports.uncertainty_verdict import (
    COVERAGE_SLACK,
    MIN_TERCILE_COVERAGE,
    N_BOOTSTRAP,
    bootstrap_within_frame,
)
from pingpong.uncertainty.learnability import SETTINGS, error_matrix, fit_on_oracle, oracle_matrix

SHARE_BAR = 0.8  # issue 38: the best estimator at >= 0.8 of the ceiling's Spearman
ERROR_FLOOR_M = 1e-3  # added to the absolute errors before their log: a hit exact to the micrometre

CAPTION = """The learnability ceiling: a GRU trained on the {n_train} training hits with the twin's oracle
log std as its target (the truth no estimator sees; pingpong.uncertainty.learnability), its within-frame
Spearman with the oracle std over frames 1-20 before the hit on the calibration and test hits, 95 %
interval from {n_boot} bootstrap resamples of whole hits. kind `ceiling`: the setting best on the calibration
hits, on the test hits; kind `single draws`: the same, the net trained on the final model's absolute
errors (out of fold on the training hits; + 1 mm before the log) rather than on the oracle std, what an
estimator has to learn from. kind `estimator`: each estimator's Spearman (uncertainty_verdict.csv) as a
share of the ceiling, beside its coverage (nominal {coverage:.2f}) and worst width tercile; meets_bar:
share >= {share_bar}, coverage within {slack:.0f} points of nominal and every width tercile >=
{tercile:.0%}."""


def _spearman_rows(u: np.ndarray, oracle: np.ndarray, rng: np.random.Generator) -> dict:
    """Within-frame Spearman (mean over ORACLE_FRAMES) of u against the oracle std (hits, 31) with its
    95 % bootstrap interval over hits."""
    columns = 30 - np.asarray(ORACLE_FRAMES)
    n = len(u)
    if n < 2:  # no ranking, and no spread to resample
        return {"n_hits": n, "spearman_oracle_1_20": np.nan, "low95": np.nan, "high95": np.nan}
    resamples = np.vstack([np.arange(n), rng.integers(0, n, size=(N_BOOTSTRAP, n))])
    boot = bootstrap_within_frame(u[:, columns], oracle[:, columns], resamples)
    return {"n_hits": n, "spearman_oracle_1_20": float(boot[0]), "low95": float(np.percentile(boot[1:], 2.5)),
            "high95": float(np.percentile(boot[1:], 97.5))}


def main(ctx):
    p = ctx.params
    torch.set_num_threads(1)
    dataset = read_table(ctx.input.dataset, DATASET)
    predictions = read_table(ctx.input.predictions, PREDICTIONS)
    oracles = read_oracles(p["sessions"], ctx.input.oracle)
    rows = join_test_hits(dataset, predictions, oracles, splits=("train", "calibration", "test"))
    oracle = oracle_matrix(dataset, rows)
    X, _ = dataset_arrays(dataset)
    matched, split = np.isfinite(oracle).all(axis=1), dataset["split"].to_numpy()
    rng = np.random.default_rng(p["seed"])
    errors = error_matrix(dataset, predictions) + ERROR_FLOOR_M
    has_error = np.isfinite(errors).all(axis=1)
    table = []
    for target, values, rows in (("oracle std", oracle, matched), ("absolute error", errors, has_error)):
        for hidden, epochs in SETTINGS:
            u = fit_on_oracle(X, values, rows & (split == "train"), hidden, epochs, p["seed"])
            for part in ("calibration", "test"):
                m = matched & (split == part)
                name = f"GRU {hidden} x {epochs} epochs"
                table.append({"kind": "setting", "trained_on": target, "part": part, "name": name,
                              **_spearman_rows(u[m], oracle[m], rng)})
    table = pd.DataFrame(table)
    ceilings = [_best_on_calibration(table[table["trained_on"] == target]) for target in
                ("oracle std", "absolute error")]
    ceilings[1] = ceilings[1].assign(kind="single draws")
    table = pd.concat([table, *ceilings, estimator_shares(pd.read_csv(ctx.input.verdict), ceilings[0].iloc[0],
                                                          p["coverage"])], ignore_index=True)
    caption = CAPTION.format(n_train=int((matched & (split == "train")).sum()), n_boot=N_BOOTSTRAP,
                             coverage=p["coverage"], share_bar=SHARE_BAR, slack=100 * COVERAGE_SLACK,
                             tercile=MIN_TERCILE_COVERAGE)
    write_report_table(table, ctx.output.md, ctx.output.csv, "Uncertainty: the learnability ceiling", caption)


def _best_on_calibration(settings: pd.DataFrame) -> pd.DataFrame:
    """The test row of the setting with the best calibration-hit Spearman, as kind `ceiling`."""
    calibration = settings[settings["part"] == "calibration"]
    rho = np.nan_to_num(calibration["spearman_oracle_1_20"].to_numpy(), nan=-2.0)
    best = calibration["name"].iloc[int(np.argmax(rho))]
    return settings[(settings["name"] == best) & (settings["part"] == "test")].assign(kind="ceiling")


def estimator_shares(verdict: pd.DataFrame, ceiling: pd.Series, coverage: float) -> pd.DataFrame:
    """Per estimator of the verdict: its Spearman with the oracle std as a share of the ceiling's, and
    whether it meets issue 38's bar (share, nominal coverage, every width tercile)."""
    out = verdict[["estimator", "spearman_oracle_1_20", "oracle_low95", "oracle_high95", "coverage",
                   "coverage_min_width_tercile"]].rename(
        columns={"estimator": "name", "oracle_low95": "low95", "oracle_high95": "high95"})
    out = out.assign(kind="estimator", part="test", n_hits=ceiling["n_hits"],
                     share_of_ceiling=out["spearman_oracle_1_20"] / ceiling["spearman_oracle_1_20"])
    out["meets_bar"] = ((out["share_of_ceiling"] >= SHARE_BAR)
                        & ((out["coverage"] - coverage).abs() <= COVERAGE_SLACK)
                        & (out["coverage_min_width_tercile"] >= MIN_TERCILE_COVERAGE))
    return out
