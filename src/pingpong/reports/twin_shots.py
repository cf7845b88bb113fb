"""Shot statistics of the twin's good shots beside published figures of human play (twin_vs_real.md).

A good shot is a row of raw/twin_truth/{session}/shots.parquet with outcome 'ok'. Its statistics: the
outgoing speed |v_out| (m/s), the spin |w_out| (rev/s), its spin type (spin_types), and the depth of its
first bounce, |y| of the first 'bounce' event of its rally and shot in events.parquet (m from the net).
Per stroke type too when the shots carry a `stroke` column.
"""

import numpy as np
import pandas as pd

from pingpong.common.atomic import write_text_atomic
from pingpong.reports.published_shots import published_for

SPIN_TYPES = ("topspin", "backspin", "sidespin", "none")
SIDESPIN_FRACTION = 0.5  # sidespin-dominant: the across-flight horizontal part of F exceeds this share of |F|
BOUNCE_BAND = (0.10, 0.70)  # m from the net; the paper: "most bounces occur for y in [-70, -10]" cm
PERCENTILES = (10, 50, 90)
# the order of the per-stroke rows
STROKES = ("drive", "loop", "push", "block", "flick", "sidespin", "smash", "fish", "lob")
SHOT_COLUMNS = ("rally", "shot", "outcome", "v_out_x", "v_out_y", "v_out_z", "w_out_x", "w_out_y", "w_out_z")
# statistic -> (label, unit); the keys are those of published_shots.PUBLISHED
STATISTICS = {
    "speed": ("outgoing speed (norm of v_out)", "m/s"),
    "spin": ("spin rate (norm of w_out)", "rev/s"),
    "topspin_share": ("share with topspin", ""),
    "backspin_share": ("share with backspin", ""),
    "sidespin_share": ("share sidespin-dominant", ""),
    "nospin_share": ("share without Magnus force", ""),
    "bounce_depth": ("first-bounce distance from the net (abs y)", "m"),
    "bounce_in_band": (f"share of first bounces {BOUNCE_BAND[0]:.2f}-{BOUNCE_BAND[1]:.2f} m from the net",
                       ""),
    # the net section (twin_flights.net_table)
    "net_height": ("net-crossing height: ball centre over the net's top edge", "m"),
    "net_high_share": ("share crossing more than 0.25 m over the net", ""),
    "net_speed": ("speed at the net (norm of v where y = 0)", "m/s"),
    "bounce_speed": ("speed before the first bounce (flight_stats speed_in)", "m/s"),
}


def spin_types(w: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Spin type of each shot ('topspin', 'backspin', 'sidespin' or 'none') from the direction of its Magnus
    force F = w x v (w: (N, 3) spin in rad/s, v: (N, 3) outgoing velocity in m/s, z up).

    - 'sidespin' (sidespin-dominant): the horizontal component of F perpendicular to v, |F_h x v_h| / |v_h|
      with F_h, v_h the horizontal parts of F and v (|F_h| for a vertical v), exceeds SIDESPIN_FRACTION |F|:
      F leans more than 30 deg out of the vertical plane through v.
    - 'backspin': not sidespin-dominant and F_z > 0 (the Magnus force lifts the ball).
    - 'topspin': not sidespin-dominant and F_z < 0 (it pushes the ball down).
    - 'none': F = 0 to rounding (|F| <= 1e-9 |w| |v|: no spin, or spin about v alone).
    The types are exclusive: a shot with backspin and a larger sidespin counts as sidespin only.
    """
    w, v = np.atleast_2d(np.asarray(w, float)), np.atleast_2d(np.asarray(v, float))
    force = np.cross(w, v)
    size = np.linalg.norm(force, axis=1)
    v_h = np.linalg.norm(v[:, :2], axis=1)
    across = np.abs(force[:, 0] * v[:, 1] - force[:, 1] * v[:, 0]) / np.where(v_h > 0, v_h, 1.0)
    side = np.where(v_h > 0, across, np.linalg.norm(force[:, :2], axis=1))
    none = size <= 1e-9 * np.linalg.norm(w, axis=1) * np.linalg.norm(v, axis=1)
    sidespin = ~none & (side > SIDESPIN_FRACTION * size)
    return np.select([none, sidespin, force[:, 2] > 0, force[:, 2] < 0],
                     ["none", "sidespin", "backspin", "topspin"], "sidespin")


def percentiles(values) -> tuple[float, float, float]:
    """The PERCENTILES (p10, p50, p90; linear interpolation) of the finite values; NaN where there are
    none."""
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    if len(values) == 0:
        return (np.nan,) * len(PERCENTILES)
    return tuple(float(q) for q in np.percentile(values, PERCENTILES))


def first_bounce_depths(shots: pd.DataFrame, events: pd.DataFrame) -> np.ndarray:
    """|y| (m from the net) of each shot's first bounce: the earliest 'bounce' event with the shot's rally and
    shot, in the order of `shots`; NaN for a shot without one."""
    bounces = events[events["kind"] == "bounce"].sort_values("time_ns", kind="stable")
    first = bounces.drop_duplicates(["rally", "shot"])[["rally", "shot", "y"]]
    merged = shots[["rally", "shot"]].merge(first, on=["rally", "shot"], how="left", validate="m:1")
    return np.abs(merged["y"].to_numpy(float))


def good_shot_table(shots: pd.DataFrame, events: pd.DataFrame) -> pd.DataFrame:
    """One row per good shot of one session: speed (m/s), spin (rev/s), spin_type, bounce_depth (m; NaN
    without a bounce) and stroke (None where `shots` has no `stroke` column)."""
    missing = [c for c in SHOT_COLUMNS if c not in shots.columns]
    if missing:
        raise ValueError(f"shots table lacks columns {missing}")
    good = shots[shots["outcome"] == "ok"].reset_index(drop=True)
    v = good[["v_out_x", "v_out_y", "v_out_z"]].to_numpy(float)
    w = good[["w_out_x", "w_out_y", "w_out_z"]].to_numpy(float)
    return pd.DataFrame({
        "speed": np.linalg.norm(v, axis=1),
        "spin": np.linalg.norm(w, axis=1) / (2 * np.pi),
        "spin_type": spin_types(w, v) if len(good) else np.array([], dtype=object),
        "bounce_depth": first_bounce_depths(good, events),
        "stroke": good["stroke"].to_numpy(object) if "stroke" in good.columns else None,
    })


def _row(statistic: str, stroke: str, values, share: bool = False) -> dict:
    """A table row: percentiles of `values`, or for a share the mean of the booleans `values`."""
    values = np.asarray(values, float)
    label, unit = STATISTICS[statistic]
    if share:
        p10, p50, p90 = np.nan, (float(values.mean()) if len(values) else np.nan), np.nan
    else:
        p10, p50, p90 = percentiles(values)
    figure, source = published_for(statistic, stroke)
    return {"statistic": label, "stroke": stroke, "n": int(np.isfinite(values).sum()), "unit": unit,
            "twin_p10": p10, "twin": p50, "twin_p90": p90, "published (human play)": figure, "source": source}


def shot_stats_table(good: pd.DataFrame) -> pd.DataFrame:
    """The twin's shot statistics (good_shot_table rows of all sessions) beside the published figures.

    Column `twin` holds the median (p50), or the share for share rows; twin_p10 / twin_p90 the 10th and
    90th percentiles. Rows for all good shots, then n, speed, spin and backspin share per stroke type when
    the shots carry strokes. Bounce rows count only the shots with a bounce.
    """
    depth = good["bounce_depth"].to_numpy(float)
    bounced = depth[np.isfinite(depth)]
    rows = [_row("speed", "all", good["speed"]), _row("spin", "all", good["spin"])]
    rows += [_row(f"{kind}_share", "all", good["spin_type"] == name, share=True)
             for kind, name in (("topspin", "topspin"), ("backspin", "backspin"),
                                ("sidespin", "sidespin"), ("nospin", "none"))]
    in_band = (bounced >= BOUNCE_BAND[0]) & (bounced <= BOUNCE_BAND[1])
    rows += [_row("bounce_depth", "all", bounced), _row("bounce_in_band", "all", in_band, share=True)]
    strokes = good["stroke"].dropna()
    for stroke in [s for s in STROKES if s in set(strokes)] + sorted(set(strokes) - set(STROKES)):
        mine = good[good["stroke"] == stroke]
        rows += [_row("speed", stroke, mine["speed"]), _row("spin", stroke, mine["spin"]),
                 _row("backspin_share", stroke, mine["spin_type"] == "backspin", share=True)]
    return pd.DataFrame(rows)


def write_sections(md_path, csv_path, title: str, sections: list[tuple[str, str, str, pd.DataFrame]]) -> None:
    """A report of several tables, each section (name, heading, caption, table): `md_path` has '# title',
    then per section '## heading' (from the second on, so the first caption reads as the page's), its
    caption and table (NaN as an empty cell); `csv_path` stacks the tables with a `section` column (the
    name) first."""
    parts = [f"# {title}"]
    for k, (_, heading, caption, table) in enumerate(sections):
        parts += [f"## {heading}"] if k else []
        cells = table.astype(object).where(table.notna(), None)  # empty cells, not 'nan'
        parts += [caption.strip(), cells.to_markdown(index=False, floatfmt=".3g", missingval="")]
    write_text_atomic(md_path, "\n\n".join(parts) + "\n")
    stacked = pd.concat([table.assign(section=name) for name, _, _, table in sections], ignore_index=True)
    write_text_atomic(csv_path, stacked[["section", *stacked.columns.drop("section")]].to_csv(index=False))
