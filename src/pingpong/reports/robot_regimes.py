"""The regime map's report: one row per cell with every controller's test hits and the values of
anticipation and of uncertainty with paired bootstrap intervals, the heatmap over the grid, the surfaces
behind the tuned controllers' choices, and the calibrated regimes against the paper's Table 2."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pingpong.robot.calibration import paper_bar, region_stats  # noqa: E402
from pingpong.robot.regime_map import (  # noqa: E402
    MAP_CONTROLLERS,
    alpha_monotone,
    best_uncertainty_controller,
    value_row,
)

TITLES = {"anticipation": "value of anticipation (anticipatory - servo), balls",
          "uncertainty": "value of uncertainty (best uncertainty controller - anticipatory), balls"}


def cell_row(cell: dict, rng: np.random.Generator, n_boot: int) -> dict:
    """One cell's row of the regime table (module docstring)."""
    results = cell["controllers"]
    row = {"cell": cell["cell"], **cell["grid_point"], "n_test": len(results["servo"]["hit"]),
           "n_calibration": cell["n_calibration_hits"]}
    row |= {f"hits_{name}": (sum(results[name]["hit"]) if name in results else np.nan)
            for name in MAP_CONTROLLERS}
    anticipation = value_row(results, "servo", "anticipatory", rng, n_boot)
    row |= {f"anticipation_{k}": v for k, v in anticipation.items()}
    best = best_uncertainty_controller(results)
    uncertainty = (value_row(results, "anticipatory", best, rng, n_boot) if best
                   else dict.fromkeys(("value", "ci95_low", "ci95_high"), np.nan))
    row |= {"uncertainty_controller": best, **{f"uncertainty_{k}": v for k, v in uncertainty.items()}}
    if "uncertainty_aware" in results:
        sweep = pd.DataFrame(results["uncertainty_aware"]["sweep"])
        full = sweep[(sweep["alpha1"] == sweep["alpha1"].max()) & (sweep["alpha2"] == sweep["alpha2"].max())]
        choice = results["uncertainty_aware"]["choice"]
        row |= {"ua_alpha1": choice["alpha1"], "ua_alpha2": choice["alpha2"],
                "ua_calibration_hits_best": int(sweep["hits"].max()),
                "ua_calibration_hits_full_alpha": int(full["hits"].max()),
                "alpha_monotone": alpha_monotone(results["uncertainty_aware"]["sweep"])}
    row |= {"sensing_noise_m": cell["sensing"]["noise_m"], "sensing_dropout": cell["sensing"]["dropout"],
            "sensing_delay_frames": cell["sensing"]["delay_frames"], "servo_fit": cell["servo_fit"]}
    return row


def regime_table(cells: list[dict], rng: np.random.Generator, n_boot: int) -> pd.DataFrame:
    return pd.DataFrame([cell_row(c, rng, n_boot) for c in cells])


def calibration_table(cells: list[dict]) -> pd.DataFrame:
    """Visual servoing's test hits by region in each given (calibrated) cell against the paper's Table 2."""
    frames = []
    for cell in cells:
        servo = cell["controllers"]["servo"]
        sim = pd.DataFrame({"region": servo["region"], "hit_ball": servo["hit"],
                            "end_distance_m": np.asarray(servo["end_distance_m"], float)})
        knobs = {k: cell["sensing"][k] for k in ("noise_m", "dropout", "delay_frames")}
        dynamics = cell.get("dynamics", {})  # cells written before the reach knobs lack it
        knobs |= {k: dynamics.get(k, np.nan) for k in ("base_speed_mps", "base_start_x_m")}
        frames.append(paper_bar(region_stats(sim)).assign(regime=cell["cell"], **knobs,
                                                          servo_fit=cell["servo_fit"]))
    columns = ["regime", "region", "n", "hits", "hit_pct", "hit_pct_ci95_low", "hit_pct_ci95_high",
               "paper_hit_pct", "paper_in_ci95", "hit_rate_within", "bar_probability_if_calibrated",
               "end_distance_mean_cm", "paper_end_distance_cm", "paper_range_low_cm", "paper_range_high_cm",
               "end_distance_within", "noise_m", "dropout", "delay_frames", "servo_fit", "base_speed_mps",
               "base_start_x_m"]
    return pd.concat(frames)[columns] if frames else pd.DataFrame(columns=columns)


def _grid(table: pd.DataFrame, axes: dict, column: str) -> tuple[np.ndarray, list, list]:
    """(values (rows, cols), row labels, column labels): the first axis down, the others across."""
    first, rest = list(axes)[0], list(axes)[1:]
    rows = axes[first]
    cols = [tuple(r) for r in pd.MultiIndex.from_product([axes[a] for a in rest]).tolist()] if rest else [()]
    values = np.full((len(rows), len(cols)), np.nan, dtype=object)
    for i, r in enumerate(rows):
        for j, c in enumerate(cols):
            match = table[(table[first] == r) & np.logical_and.reduce(
                [table[a] == v for a, v in zip(rest, c, strict=True)] or [np.ones(len(table), bool)])]
            if len(match):
                values[i, j] = match.iloc[0][column]
    col_labels = [", ".join(f"{a} {v:g}" for a, v in zip(rest, c, strict=True)) for c in cols]
    return values, [f"{first} {r:g}" for r in rows], col_labels


def regime_map_figure(table: pd.DataFrame, axes: dict, path) -> None:
    """Heatmaps of the values of anticipation and of uncertainty over the grid, each cell annotated with
    the value and its interval."""
    grid = table.dropna(subset=list(axes))
    fig, panels = plt.subplots(1, 2, figsize=(12, 1.2 + 1.1 * len(list(axes.values())[0])), squeeze=False)
    for ax, what in zip(panels[0], ("anticipation", "uncertainty"), strict=True):
        values, row_labels, col_labels = _grid(grid, axes, f"{what}_value")
        low, _, _ = _grid(grid, axes, f"{what}_ci95_low")
        high, _, _ = _grid(grid, axes, f"{what}_ci95_high")
        numbers = values.astype(float)
        bound = max(np.nanmax(np.abs(numbers)) if np.isfinite(numbers).any() else 1.0, 1.0)
        ax.imshow(numbers, cmap="RdBu", vmin=-bound, vmax=bound, aspect="auto")
        for i in range(numbers.shape[0]):
            for j in range(numbers.shape[1]):
                if np.isfinite(numbers[i, j]):
                    text = f"{numbers[i, j]:+.0f}\n[{float(low[i, j]):+.0f}, {float(high[i, j]):+.0f}]"
                    ax.text(j, i, text, ha="center", va="center", fontsize=9)
        ax.set_xticks(range(len(col_labels)), col_labels, fontsize=8)
        ax.set_yticks(range(len(row_labels)), row_labels, fontsize=8)
        ax.set_title(TITLES[what], fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def surface_figure(cell: dict, path) -> None:
    """The calibration hits over alpha1 x alpha2 (uncertainty-aware) and over the confidence ramp's
    u_full x u_zero (confidence-scaled on the estimator and on the oracle), one panel each that ran."""
    sweeps = {name: pd.DataFrame(cell["controllers"][name]["sweep"]) for name in
              ("uncertainty_aware", "confidence_scaled", "confidence_scaled_oracle")
              if name in cell["controllers"]}
    n = max(len(sweeps), 1)
    fig, panels = plt.subplots(1, n, figsize=(4.2 * n, 3.8), squeeze=False)
    for ax, (name, sweep) in zip(panels[0], sweeps.items(), strict=False):
        x, y = ("alpha1", "alpha2") if name == "uncertainty_aware" else ("u_full", "u_zero")
        table = sweep.pivot_table(index=y, columns=x, values="hits", aggfunc="max")
        image = ax.imshow(table.to_numpy(float), origin="lower", cmap="viridis", aspect="auto")
        scale = 1.0 if x == "alpha1" else 100.0  # the ramp's ends in cm
        ax.set_xticks(range(len(table.columns)), [f"{v * scale:.3g}" for v in table.columns], fontsize=7)
        ax.set_yticks(range(len(table.index)), [f"{v * scale:.3g}" for v in table.index], fontsize=7)
        ax.set_xlabel(x if scale == 1 else f"{x} (cm)"), ax.set_ylabel(y if scale == 1 else f"{y} (cm)")
        for (i, j), hits in np.ndenumerate(table.to_numpy(float)):
            if np.isfinite(hits):
                ax.text(j, i, f"{hits:.0f}", ha="center", va="center", fontsize=7, color="w")
        ax.set_title(f"{name}: calibration hits", fontsize=9)
        fig.colorbar(image, ax=ax, shrink=0.8)
    fig.suptitle(f"regime {cell['cell']} ({cell['n_calibration_hits']} calibration hits)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
