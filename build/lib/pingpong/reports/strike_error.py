"""The paper's Table 1: median strike-point error (cm) by region, and its course over t = -30 .. 0."""

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pingpong.common.atomic import atomic_path  # noqa: E402

REGIONS = ("right", "centre", "left")


def with_mean_baseline(predictions: pd.DataFrame) -> pd.DataFrame:
    """Adds model 'mean': every test hit predicted at the training hits' mean strike x."""
    hits = predictions[(predictions["split"] == "train") & (predictions["model"] == "final")]
    mean_x = hits.drop_duplicates(["session", "rally", "hit"])["strike_x"].mean()
    test = predictions[(predictions["split"] == "test") & (predictions["model"] == "final")].copy()
    test["model"] = "mean"
    test["strike_x_pred"] = mean_x
    test["abs_error"] = np.abs(test["strike_x"] - mean_x)
    return pd.concat([predictions, test], ignore_index=True)


def error_by_frame(predictions: pd.DataFrame) -> pd.DataFrame:
    """Median absolute strike error (cm) on the test part per model, frame before the hit and region."""
    test = predictions[predictions["split"] == "test"]
    by_region = test.groupby(["model", "frames_before_hit", "region"])["abs_error"].median().unstack("region")
    by_region["all"] = test.groupby(["model", "frames_before_hit"])["abs_error"].median()
    counts = test.groupby(["model", "frames_before_hit"]).size().rename("n_hits")
    return (100 * by_region.reindex(columns=[*REGIONS, "all"])).join(counts).reset_index()


def table1(by_frame: pd.DataFrame, frames=(10, 1, 0)) -> pd.DataFrame:
    """Rows: model and frames before the hit (10 and 1 as the paper, 0 added); columns: regions, all (cm)."""
    rows = by_frame[by_frame["frames_before_hit"].isin(frames)]
    return rows.sort_values(["model", "frames_before_hit"], ascending=[True, False]).reset_index(drop=True)


def plot_error_vs_frames(by_frame: pd.DataFrame, path) -> None:
    fig, ax = plt.subplots(figsize=(6, 4))
    for model, rows in by_frame.groupby("model"):
        ax.plot(-rows["frames_before_hit"], rows["all"], marker=".", label=model)
    ax.set_xlabel("frames before the hit (100 Hz)")
    ax.set_ylabel("median strike-point error (cm)")
    ax.set_title("Strike-point error on the test hits")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120)
    plt.close(fig)
