"""The twin's ball flights beside the real MPI ball-gun flights, and where they cross the net (issue: twin vs
real table)."""

import numpy as np
import pandas as pd

from pingpong.frames import FRAME_NS, NET_HEIGHT
from pingpong.reports.published_shots import NOT_FOUND, published_for
from pingpong.reports.twin_shots import STATISTICS, STROKES, percentiles
from pingpong.twin.realdata import flight_stats
from pingpong.twin.repertoire import STROKES as STROKE_KINDS

HIGH_OVER_NET = 0.25  # m over the net's top edge: issue 41's high ball (>= 8 % of good shots)
# The strokes whose net-crossing heights no published measurement gives (pingpong.twin.repertoire's doc: the
# search and what it found): their aimed ranges are the project's choice, and the net table says so.
CHOSEN_NET_HEIGHTS = ("drive", "loop", "sidespin", "push", "flick", "block", "smash")
NET_COLUMNS = ("statistic", "stroke", "n", "unit", "twin_p10", "twin", "twin_p90", "real_p10", "real",
               "real_p90", "published (human play)", "source")


def twin_flight_stats(ball: pd.DataFrame, shots: pd.DataFrame) -> list[dict]:
    """flight_stats of every good shot's flight (hit to the receiver), sampled at the camera rate."""
    stats = []
    for shot in shots[shots["outcome"] == "ok"].itertuples():
        rows = ball[(ball["rally"] == shot.rally) & (ball["shot"] == shot.shot)]
        t_ns = rows["time_ns"].to_numpy()
        keep = np.searchsorted(t_ns, np.arange(t_ns[0], t_ns[-1], FRAME_NS))  # 100 Hz, like the cameras
        rows = rows.iloc[np.unique(keep)]
        times = (rows["time_ns"].to_numpy() - t_ns[0]) / 1e9
        try:
            stats.append(flight_stats(times, rows[["x", "y", "z"]].to_numpy(),
                                      rows[["vx", "vy", "vz"]].to_numpy()))
        except ValueError:  # too few samples either side of the bounce to fit
            continue
    return stats


def net_crossings(ball: pd.DataFrame, shots: pd.DataFrame) -> pd.DataFrame:
    """Where each good shot first crosses the net plane y = 0, from the twin's 1 kHz flight samples (linear
    interpolation between the two either side): `height` the ball centre's height over the net's top edge
    (z - NET_HEIGHT, m; negative: below the tape, beside the net posts), `speed` |v| there (m/s). One row per
    good shot whose samples cross: rally, shot, stroke (None without a stroke column), height, speed."""
    good = shots[shots["outcome"] == "ok"]
    flights = ball.groupby(["rally", "shot"], sort=False)
    rows = []
    for shot in good.itertuples():
        try:
            rows_of = flights.get_group((shot.rally, shot.shot))
        except KeyError:
            continue
        y = rows_of["y"].to_numpy(float)
        i = np.flatnonzero(np.sign(y[:-1]) * np.sign(y[1:]) < 0)
        if len(i) == 0:
            continue
        i = int(i[0])
        f = y[i] / (y[i] - y[i + 1])
        z = rows_of["z"].to_numpy(float)
        v = rows_of[["vx", "vy", "vz"]].to_numpy(float)
        rows.append({"rally": shot.rally, "shot": shot.shot, "stroke": getattr(shot, "stroke", None),
                     "height": z[i] + f * (z[i + 1] - z[i]) - NET_HEIGHT,
                     "speed": float(np.linalg.norm(v[i] + f * (v[i + 1] - v[i])))})
    return pd.DataFrame(rows, columns=["rally", "shot", "stroke", "height", "speed"])


def _net_row(statistic: str, stroke: str, twin, real=(), share: bool = False) -> dict:
    """A row of net_table: percentiles (or for a share the mean of the booleans) of the twin's values and
    the real ball gun's (empty where it has none), beside the published figures."""
    label, unit = STATISTICS[statistic]
    twin = np.asarray(twin, float)
    if share:
        t10, t50, t90 = np.nan, (float(twin.mean()) if len(twin) else np.nan), np.nan
    else:
        t10, t50, t90 = percentiles(twin)
    r10, r50, r90 = percentiles(real) if len(real) else (np.nan,) * 3
    figure, source = published_for(statistic, stroke)
    if statistic == "net_height" and stroke in CHOSEN_NET_HEIGHTS:
        low, high = STROKE_KINDS[stroke].net_height
        found = "no published measurement found" if figure == NOT_FOUND else f"{figure}; no height measured"
        figure = f"{found}: the twin's aim, {low:.2f}-{high:.2f} m over the net, is the project's choice"
    return dict(zip(NET_COLUMNS, (label, stroke, int(np.isfinite(twin).sum()), unit, t10, t50, t90, r10, r50,
                                  r90, figure, source), strict=True))


def net_table(crossings: pd.DataFrame, twin_stats: list[dict], real_stats: list[dict]) -> pd.DataFrame:
    """The good shots' net-crossing height and speed at the net (net_crossings of all sessions), overall and
    per stroke, the share higher than HIGH_OVER_NET, and the speed before the first bounce of the twin's
    flights and of the real ball-gun flights (flight_stats' speed_in: the recordings carry no net
    position, so the ball gun has no net-crossing figures)."""
    height, speed = crossings["height"], crossings["speed"]
    rows = [_net_row("net_height", "all", height),
            _net_row("net_high_share", "all", height > HIGH_OVER_NET, share=True),
            _net_row("net_speed", "all", speed),
            _net_row("bounce_speed", "all", [s["speed_in"] for s in twin_stats],
                     [s["speed_in"] for s in real_stats])]
    strokes = crossings["stroke"].dropna()
    for stroke in [s for s in STROKES if s in set(strokes)] + sorted(set(strokes) - set(STROKES)):
        mine = crossings[crossings["stroke"] == stroke]
        rows += [_net_row("net_height", stroke, mine["height"]), _net_row("net_speed", stroke, mine["speed"])]
    return pd.DataFrame(rows, columns=list(NET_COLUMNS))
