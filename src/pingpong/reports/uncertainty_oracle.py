"""The twin's strike oracle against the final model: how much of the model's strike-x error no estimator
could remove, and which of the player's choices leave the strike point open.

The oracle (raw/twin_truth/{session}/strike_oracle.parquet) gives, per good shot and frame before the
hit, the distribution of the strike x over re-draws of every random choice the player had not yet made
at that frame; its spread is what no estimator fed that frame can know. Its x is in the table frame,
the kept hits' in the mirrored one (curation.labels: x -> -x for a far hitter), so it is mirrored alike.
"""

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pingpong.common.artifacts import read_table  # noqa: E402
from pingpong.common.atomic import atomic_path, write_text_atomic  # noqa: E402
from pingpong.curation.schemas import HIT_KEYS  # noqa: E402
from pingpong.reports.curation_accuracy import nearest_shot  # noqa: E402
from pingpong.twin import truth  # noqa: E402
from pingpong.uncertainty.metrics import ause, spearman  # noqa: E402

FINAL = "final"  # predictions' model: the selected configuration refit on the training part
ORACLE_X = ["oracle_mean_x", "oracle_std_x", "oracle_q05_x", "oracle_q95_x"]
SHOT_KEYS = ["session", "rally", "shot"]
CAUSE_FRAMES = (30, 20, 10, 5, 1, 0)
CV_FRAME = 10  # the issue asks for a CV of the oracle std >= 0.5 here on the default twin
ORDER = {"all": ("all",),
         "stroke": ("drive", "loop", "push", "block", "flick", "sidespin", "smash"),
         "deception": ("telegraph", "neutral", "disguise"),
         "pressure": ("low", "mid", "high")}  # terciles of the incoming ball's time pressure


def mirror_oracle(oracle: pd.DataFrame, far) -> pd.DataFrame:
    """The oracle's x columns after x -> -x where `far`: the mean flips, the 5 % and 95 % quantiles swap
    (and flip), the spread stays."""
    far = np.asarray(far, bool)
    out = oracle.copy()
    out["oracle_mean_x"] = np.where(far, -oracle["oracle_mean_x"], oracle["oracle_mean_x"])
    out["oracle_q05_x"] = np.where(far, -oracle["oracle_q95_x"], oracle["oracle_q05_x"])
    out["oracle_q95_x"] = np.where(far, -oracle["oracle_q05_x"], oracle["oracle_q95_x"])
    return out


def join_test_hits(dataset: pd.DataFrame, predictions: pd.DataFrame,
                   oracles: dict[str, pd.DataFrame], splits=("test",)) -> pd.DataFrame:
    """One row per matched hit of `splits` and frame before the hit: the final model's strike_x (label),
    strike_x_pred and abs_error beside its shot's oracle, mirrored like the hit, and the hit's split.

    A hit's shot is the session's oracle shot with the nearest t_hit_ns within one frame
    (curation_accuracy.nearest_shot); a hit with none is left out (the stage's caption counts them).
    The shot's keys come as twin_rally, twin_shot: curation numbers rallies its own way.
    """
    test = dataset.loc[dataset["split"].isin(splits), [*HIT_KEYS, "split", "hitter", "t_hit_ns"]]
    twin = {"rally": "twin_rally", "shot": "twin_shot", "t_hit_ns": "twin_t_hit_ns"}
    parts = []
    for session, hits in test.groupby("session"):
        oracle = oracles[session][[*twin, "frames_before_hit", *ORACLE_X]].rename(columns=twin)
        shots = oracle.drop_duplicates(["twin_rally", "twin_shot"]).reset_index(drop=True)
        at = nearest_shot(shots.rename(columns={"twin_t_hit_ns": "t_hit_ns"}), hits["t_hit_ns"])
        found = hits[at >= 0].assign(twin_rally=shots["twin_rally"].to_numpy()[at[at >= 0]],
                                     twin_shot=shots["twin_shot"].to_numpy()[at[at >= 0]])
        parts.append(found.merge(oracle, on=["twin_rally", "twin_shot"]))
    final = predictions.loc[(predictions["model"] == FINAL) & predictions["split"].isin(splits),
                            [*HIT_KEYS, "frames_before_hit", "strike_x", "strike_x_pred", "abs_error"]]
    empty = pd.DataFrame(columns=[*test, *twin.values(), "frames_before_hit", *ORACLE_X])  # no test hits
    matched = pd.concat(parts, ignore_index=True) if parts else empty
    joined = matched.merge(final, on=[*HIT_KEYS, "frames_before_hit"], validate="one_to_one")
    return mirror_oracle(joined, joined["hitter"] == "far").sort_values(
        [*HIT_KEYS, "frames_before_hit"]).reset_index(drop=True)


def by_frame_table(joined: pd.DataFrame) -> pd.DataFrame:
    """Per frame before the hit (30 .. 0), over the matched test hits (test_hits_with_oracle).

    spearman: within-frame Spearman rho between the oracle std and the model's absolute error. ause: the
    oracle std's AUSE against that error: the area, over removing 0 .. 95 % of the hits, between the mean
    error left when the largest oracle stds are removed first and when the largest errors are (both over
    all hits' mean error; uncertainty.metrics.ause); 0: the oracle orders the errors exactly.
    irreducible_share: mean oracle variance / the model's MSE, misfit_share 1 - that (below 0 when the
    model beats the oracle's spread on these hits by luck; reported as is). coverage_q05_q95: share of
    labels inside the oracle's [q05, q95] (nominally 0.9).
    """
    rows = []
    for frame, g in joined.groupby("frames_before_hit"):
        std, err = g["oracle_std_x"].to_numpy(float), g["abs_error"].to_numpy(float)
        mse = float(np.mean(err**2))
        share = float(np.mean(std**2)) / mse if mse > 0 else float("nan")
        inside = (g["oracle_q05_x"] <= g["strike_x"]) & (g["strike_x"] <= g["oracle_q95_x"])
        rows.append({"frames_before_hit": int(frame), "n_hits": len(g), "spearman": spearman(std, err),
                     "ause": ause(std, err), "oracle_std_cm": 100 * std.mean(),
                     "oracle_std_cv": _cv(std), "model_mse_cm2": 1e4 * mse, "irreducible_share": share,
                     "misfit_share": 1 - share, "coverage_q05_q95": float(inside.mean())})
    columns = ["frames_before_hit", "n_hits", "spearman", "ause", "oracle_std_cm", "oracle_std_cv",
               "model_mse_cm2", "irreducible_share", "misfit_share", "coverage_q05_q95"]
    table = pd.DataFrame(rows, columns=columns)
    return table.sort_values("frames_before_hit", ascending=False).reset_index(drop=True)


def _cv(values) -> float:
    """Coefficient of variation (population std / mean); NaN for no values or a zero mean."""
    values = np.asarray(values, float)
    return float(values.std() / values.mean()) if values.size and values.mean() > 0 else float("nan")


def oracle_with_causes(oracle: pd.DataFrame, shots: pd.DataFrame) -> pd.DataFrame:
    """One session's oracle rows beside their shot's stroke, deception and pressure (joined on rally,
    shot and t_hit_ns). An oracle row without its shot is an error: the two tables disagree."""
    causes = shots[["rally", "shot", "t_hit_ns", "stroke", "deception", "pressure"]]
    rows = oracle.merge(causes, on=["rally", "shot", "t_hit_ns"], validate="many_to_one")
    if len(rows) != len(oracle):
        raise ValueError(f"{len(oracle) - len(rows)} oracle rows have no shot of the same rally, shot and "
                         f"t_hit_ns in shots.parquet")
    return rows


def with_pressure_tercile(rows: pd.DataFrame) -> tuple[pd.DataFrame, np.ndarray]:
    """(rows with pressure_tercile low/mid/high, the edges [min, q1/3, q2/3, max]); terciles over shots
    (each shot once, whatever its frames), low = [min, q1/3], mid = (q1/3, q2/3], high = (q2/3, max]."""
    pressure = rows.drop_duplicates(SHOT_KEYS)["pressure"].to_numpy(float)
    edges = np.quantile(pressure, [0, 1 / 3, 2 / 3, 1]) if pressure.size else np.full(4, np.nan)
    k = np.searchsorted(edges[1:3], rows["pressure"].to_numpy(float), side="left")
    return rows.assign(pressure_tercile=np.asarray(ORDER["pressure"], object)[k]), edges


def _groups(rows: pd.DataFrame):
    """(cause, value, rows of that value) in ORDER, then any value ORDER does not know, by name."""
    for cause, column in (("all", None), ("stroke", "stroke"), ("deception", "deception"),
                          ("pressure", "pressure_tercile")):
        values = pd.Series("all", index=rows.index) if column is None else rows[column]
        known = ORDER[cause]
        for value in sorted(values.unique(), key=lambda v: (known.index(v) if v in known else len(known), v)):
            yield cause, value, rows[values == value]


def std_by_cause(rows: pd.DataFrame) -> pd.DataFrame:
    """Long table: cause, value, frames_before_hit, oracle_std_cm (mean over the value's shots) for every
    frame; cause 'all' holds every shot. rows: oracle_with_causes of every session, with a session column."""
    rows, _ = with_pressure_tercile(rows)
    parts = [g.groupby("frames_before_hit")["oracle_std_x"].mean().mul(100).rename("oracle_std_cm")
             .reset_index().assign(cause=cause, value=value) for cause, value, g in _groups(rows)]
    return pd.concat(parts, ignore_index=True)[["cause", "value", "frames_before_hit", "oracle_std_cm"]]


def causes_table(rows: pd.DataFrame) -> pd.DataFrame:
    """One row per cause value: its shots, mean oracle std (cm) at CAUSE_FRAMES and the CV of the oracle
    std at CV_FRAME over its shots; pressure rows carry their tercile's bounds."""
    rows, edges = with_pressure_tercile(rows)
    out = []
    for cause, value, g in _groups(rows):
        by_frame = g.groupby("frames_before_hit")["oracle_std_x"]
        mean_cm = 100 * by_frame.mean()
        row = {"cause": cause, "value": value, "pressure_from": np.nan, "pressure_to": np.nan,
               "n_shots": len(g.drop_duplicates(SHOT_KEYS))}
        if cause == "pressure":
            k = ORDER["pressure"].index(value)
            row["pressure_from"], row["pressure_to"] = float(edges[k]), float(edges[k + 1])
        row |= {f"oracle_std_cm_f{f}": float(mean_cm.get(f, np.nan)) for f in CAUSE_FRAMES}
        row[f"oracle_std_cv_f{CV_FRAME}"] = _cv(g.loc[g["frames_before_hit"] == CV_FRAME, "oracle_std_x"])
        out.append(row)
    return pd.DataFrame(out)


def plot_std_by_cause(long: pd.DataFrame, path) -> None:
    """Mean oracle std (cm) against frames before the hit, one panel per cause, one line per value and
    every shot dashed in each."""
    causes = [c for c in ORDER if c != "all"]
    fig, axes = plt.subplots(1, len(causes), figsize=(13, 4), sharey=True)
    every = long[long["cause"] == "all"]
    for ax, cause in zip(axes, causes, strict=True):
        for value, g in long[long["cause"] == cause].groupby("value", sort=False):
            ax.plot(-g["frames_before_hit"], g["oracle_std_cm"], marker=".", label=value)
        ax.plot(-every["frames_before_hit"], every["oracle_std_cm"], "k--", lw=1, label="all shots")
        ax.set_title(cause)
        ax.set_xlabel("frames before the hit (100 Hz)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("mean oracle std of strike x (cm)")
    fig.suptitle("What the player has not yet chosen: the strike oracle's spread")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120)
    plt.close(fig)


def write_oracle_report(by_frame: pd.DataFrame, causes: pd.DataFrame, md_path, csv_path, title: str,
                        caption: str, causes_caption: str) -> None:
    """Both tables in one Markdown file (each under its caption) and one CSV: their rows stacked, a
    `table` column ('by_frame' or 'causes') first, the other table's columns empty."""
    text = (f"# {title}\n\n{caption.strip()}\n\n{by_frame.to_markdown(index=False, floatfmt='.3g')}\n\n"
            f"## Causes\n\n{causes_caption.strip()}\n\n{causes.to_markdown(index=False, floatfmt='.3g')}\n")
    write_text_atomic(md_path, text)
    stacked = pd.concat([by_frame.assign(table="by_frame"), causes.assign(table="causes")], ignore_index=True)
    counts = [c for t in (by_frame, causes) for c in t if pd.api.types.is_integer_dtype(t[c])]
    stacked[counts] = stacked[counts].astype("Int64")  # stay integers beside the other table's blanks
    write_text_atomic(csv_path, stacked[["table", *by_frame, *causes]].to_csv(index=False))


def read_oracles(sessions, paths) -> dict[str, pd.DataFrame]:
    """Each session's strike oracle (raw/twin_truth/{session}/strike_oracle.parquet), by session."""
    return {s: read_table(path, truth.ORACLE) for s, path in zip(sessions, paths, strict=True)}


def as_uncertainty(rows: pd.DataFrame, missing: float = np.nan) -> pd.DataFrame:
    """Oracle rows with the uncertainty table's columns: uncertainty = std = the oracle std (`missing`
    where the row has none), the interval its [q05, q95]."""
    std = rows["oracle_std_x"].fillna(missing)
    return rows.assign(uncertainty=std, std=std, lower=rows["oracle_q05_x"], upper=rows["oracle_q95_x"])


def oracle_uncertainty(dataset: pd.DataFrame, predictions: pd.DataFrame,
                       oracles: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """The oracle as an uncertainty table (uncertainty.schemas.UNCERTAINTY) of the calibration and test
    hits: uncertainty = std = the oracle std, the interval its [q05, q95]. For the robot's ceiling of
    confidence scaling only: it is the twin's truth, which no estimator sees."""
    splits = ("calibration", "test")
    keys = [*HIT_KEYS, "frames_before_hit"]
    matched = join_test_hits(dataset, predictions, oracles, splits)[[*keys, *ORACLE_X]]
    final = predictions.loc[(predictions["model"] == FINAL) & predictions["split"].isin(splits),
                            [*keys, "split", "strike_x", "strike_x_pred", "abs_error"]]
    rows = final.merge(matched, on=keys, how="left", validate="one_to_one").sort_values(keys)
    # a hit no twin shot matched has no oracle: infinite uncertainty, so a confidence ramp never trusts it
    return as_uncertainty(rows, missing=np.inf).reset_index(drop=True)
