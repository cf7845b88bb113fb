"""The simulation figure: each (test hit, controller) episode at the strike, in two orthogonal views.

A cell has a top view (y across, x up) above a side view (y across, z up) sharing the y axis: the
robot's end (-y) on the left, the opponent's on the right. Each shows the table and net, the strike line,
the ball's whole flight (the input sequence's frames, then the measured flight) and where it crosses the
strike line, the model's last prediction before the hit (its path on the table and its strike point),
the robot at the strike (base, arm links through the joint frames, paddle disc) with the paddle's path
until then, and the opponent at the hit (the last frame with joints). Two flat views rather than one 3D
axes: matplotlib's 3D does not sort depth between objects, so the table hid the arm above it, and the
flat views show the strike error's two components (x above, z below) directly.
Positions in the scene's (mirrored) table frame, m.
"""

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Circle, Polygon, Rectangle  # noqa: E402

from pingpong.common.atomic import atomic_path  # noqa: E402
from pingpong.frames import (  # noqa: E402
    BALL_RADIUS,
    MODEL_BONES,
    NET_HEIGHT,
    NET_OVERHANG,
    STRIKE_Y,
    TABLE_HALF_LENGTH,
    TABLE_HALF_WIDTH,
)
from pingpong.robot.model import PADDLE_RADIUS  # noqa: E402
from pingpong.robot.scene import (  # noqa: E402
    TABLE_THICKNESS,
    SceneEpisode,
    arm_points,
    predicted_path,
    robot_pose,
    shape_size,
)

TOP, SIDE = (1, 0), (1, 2)  # (horizontal, vertical) axes of the table frame in each view
Y_LIMITS = (-3.0, 2.2)  # m: behind the robot's base to behind the opponent
V_LIMITS = {TOP: (-1.25, 1.25), SIDE: (-0.76, 1.7)}  # x across the table; z from the floor up
FLOOR_Z = -0.76
COLORS = {"table": "#1a3d85", "ball": "#ff8c00", "strike": "#ffd700", "prediction": "#8c33cc",
          "goal": "#1ab34d", "arm": "#f27319", "steel": "#73737f", "paddle": "#cc1a1a",
          "opponent": "#2673e6"}


def show_index(scene: SceneEpisode) -> int:
    """The frame shown: the one nearest the strike (the last frame when the ball never reaches the line)."""
    if not np.isfinite(scene.t_strike):
        return len(scene.times) - 1
    return int(np.argmin(np.abs(scene.times - scene.t_strike)))


def disc(centre: np.ndarray, rotation: np.ndarray, radius: float = PADDLE_RADIUS, n: int = 24) -> np.ndarray:
    """(n, 3) points of a disc's rim: centre, normal = rotation's z axis."""
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return centre + radius * (np.cos(angle)[:, None] * rotation[:, 0]
                              + np.sin(angle)[:, None] * rotation[:, 1])


def _xy(points, view) -> tuple[np.ndarray, np.ndarray]:
    points = np.asarray(points, float)
    return points[..., view[0]], points[..., view[1]]


def _patch(ax, points, view, **style) -> None:
    """A filled outline of 3D points, projected (a box's corners, a disc's rim)."""
    h, v = _xy(points, view)
    if len(h) > 4:  # a rim: its points go round in order
        ax.add_patch(Polygon(np.column_stack([h, v]), closed=True, **style))
    else:
        ax.add_patch(Rectangle((h.min(), v.min()), np.ptp(h), np.ptp(v), **style))


def _draw_table(ax, view) -> None:
    h, w = TABLE_HALF_LENGTH, TABLE_HALF_WIDTH
    if view == TOP:
        ax.add_patch(Rectangle((-h, -w), 2 * h, 2 * w, facecolor=COLORS["table"], edgecolor="white", lw=1.5))
        ax.plot([-h, h], [0, 0], color="white", lw=0.6)  # the centre line
        ax.plot([0, 0], [-w - NET_OVERHANG, w + NET_OVERHANG], color="0.6", lw=2)
    else:
        ax.add_patch(Rectangle((-h, -TABLE_THICKNESS), 2 * h, TABLE_THICKNESS, color=COLORS["table"]))
        ax.plot([0, 0], [0, NET_HEIGHT], color="0.6", lw=2)
        ax.axhline(FLOOR_Z, color="0.4", lw=1)
        for y in (-0.9 * h, 0.9 * h):
            ax.plot([y, y], [FLOOR_Z, -TABLE_THICKNESS], color="0.5", lw=1.5)  # legs
    ax.axvline(STRIKE_Y, color=COLORS["goal"], lw=0.8, ls=":")


def _draw_robot(ax, pose: dict, view) -> None:
    for _, shape, placement in pose["visuals"]:
        if hasattr(shape, "halfSide"):  # the base
            corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) / 2
            points = placement.translation + (corners * shape_size(shape)) @ placement.rotation.T
            _patch(ax, points[[0, 7]], view, facecolor="0.85", edgecolor=COLORS["steel"], lw=1)
        else:  # the paddle
            rim = disc(placement.translation, placement.rotation, shape_size(shape)[0] / 2)
            _patch(ax, rim, view, facecolor=COLORS["paddle"], edgecolor="k", lw=0.4, zorder=5)
    arm = arm_points(pose)
    ax.plot(*_xy(arm, view), color=COLORS["arm"], lw=4, solid_capstyle="round", zorder=4)
    ax.plot(*_xy(arm[1:-2], view), ls="", marker="o", ms=3, color=COLORS["steel"], zorder=4)


def _draw_opponent(ax, scene: SceneEpisode, view) -> None:
    seen = np.flatnonzero(np.isfinite(scene.joints).all(axis=(1, 2)))
    if len(seen) == 0:
        return
    i = seen[-1]
    for a, b in MODEL_BONES:
        ax.plot(*_xy(scene.joints[i, [a, b]], view), color=COLORS["opponent"], lw=2)
    rim = disc(scene.opponent_paddle[i], scene.opponent_paddle_rotation[i])
    _patch(ax, rim, view, facecolor=COLORS["paddle"], edgecolor="k", lw=0.4)


def _draw_prediction(ax, scene: SceneEpisode, view) -> None:
    before = np.flatnonzero((scene.times <= 0) & np.isfinite(scene.labels).all(axis=1))
    if len(before) == 0:
        return
    i = before[-1]  # the last prediction before the hit
    if view == TOP:
        ax.plot(*_xy(predicted_path(scene.labels[i]), view), color=COLORS["prediction"], lw=1.2, ls="--")
    strike = (scene.predicted_strike[i, 0], STRIKE_Y, scene.predicted_strike[i, 1])
    ax.plot(*_xy(strike, view), ls="", marker="X", ms=7, color=COLORS["prediction"], zorder=6)


def draw_view(ax, scene: SceneEpisode, poses: list[dict], view) -> None:
    """One view of the scene at the shown frame (poses: the robot at every frame up to it)."""
    _draw_table(ax, view)
    seen = np.isfinite(scene.ball).all(axis=1)
    before = seen & (scene.times < 0)  # the ball coming to the opponent, faint: the flight is what counts
    ax.plot(*_xy(scene.ball[before], view), color=COLORS["ball"], lw=0.6, ls=":", alpha=0.6, zorder=3)
    after = seen & (scene.times >= 0)
    ax.plot(*_xy(scene.ball[after], view), color=COLORS["ball"], lw=1, marker=".", ms=3, zorder=3)
    if np.isfinite(scene.ball_strike).all():
        ax.plot(*_xy(scene.ball_strike, view), ls="", marker="*", ms=11, color=COLORS["strike"], mec="k",
                mew=0.5, zorder=7)
    _draw_prediction(ax, scene, view)
    paddle_path = np.array([pose["frames"]["paddle"].translation for pose in poses])
    ax.plot(*_xy(paddle_path, view), color=COLORS["paddle"], lw=0.8, zorder=4)
    _draw_robot(ax, poses[-1], view)
    _draw_opponent(ax, scene, view)
    ax.set_xlim(*Y_LIMITS)
    ax.set_ylim(*V_LIMITS[view])
    ax.set_aspect("equal")
    ax.tick_params(labelsize=6)
    ax.set_ylabel("x (m)" if view == TOP else "z (m)", fontsize=7, labelpad=1)


def draw_strike(ax, scene: SceneEpisode) -> None:
    """The strike plane (x, z) around the strike: the ball there and the paddle's disc, whose 8 cm radius is
    what the hit criterion allows (both lie on the strike line, so the 3D distance is the one seen here)."""
    if not (np.isfinite(scene.ball_strike).all() and np.isfinite(scene.paddle_strike).all()):
        ax.set_axis_off()
        return
    ball, paddle = scene.ball_strike[[0, 2]], scene.paddle_strike[[0, 2]]
    ax.add_patch(Circle(paddle, PADDLE_RADIUS, facecolor=COLORS["paddle"], edgecolor=COLORS["paddle"],
                        alpha=0.35))
    ax.add_patch(Circle(ball, BALL_RADIUS, facecolor=COLORS["ball"], edgecolor="k", lw=0.5))
    ax.plot(*paddle, marker="+", color="k", ms=6)
    centre = (ball + paddle) / 2
    half = max(0.15, 0.6 * np.abs(ball - paddle).max() + PADDLE_RADIUS)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=5, pad=1)
    ax.set_title("at the strike line: x, z", fontsize=6, pad=2)


def draw_cell(top_ax, side_ax, scene: SceneEpisode, robot, visuals) -> None:
    """A scene's top and side views at show_index, titled with the controller and the outcome, and the strike
    plane zoomed in an inset above the table (where the side view is empty)."""
    i = show_index(scene)
    poses = [robot_pose(robot, visuals, q) for q in scene.q[: i + 1]]
    draw_view(top_ax, scene, poses, TOP)
    draw_view(side_ax, scene, poses, SIDE)
    draw_strike(side_ax.inset_axes([0.42, 0.5, 0.3, 0.44]), scene)
    top_ax.tick_params(labelbottom=False)
    side_ax.set_xlabel("y (m)", fontsize=7, labelpad=1)
    info = scene.info
    outcome = "hit" if info["hit_ball"] else "miss"
    top_ax.set_title(f"{info['controller']}: {outcome}, {100 * info['end_distance_m']:.1f} cm "
                     f"(t = {scene.times[i]:.2f} s)", fontsize=9)


LEGEND = [Line2D([], [], color=COLORS["ball"], marker=".", label="ball"),
          Line2D([], [], color=COLORS["strike"], marker="*", ms=10, ls="", mec="k",
                 label="ball at the strike line"),
          Line2D([], [], color=COLORS["prediction"], marker="X", ls="--",
                 label="last prediction before the hit"),
          Line2D([], [], color=COLORS["arm"], lw=4, label="robot at the strike"),
          Line2D([], [], color=COLORS["paddle"], lw=0.8, label="robot's paddle path"),
          Line2D([], [], color=COLORS["opponent"], lw=2, label="opponent at the hit"),
          Line2D([], [], color=COLORS["goal"], ls=":", label="strike line")]


def plot_scenes(scenes: list[SceneEpisode], robot, visuals, path) -> None:
    """A grid of cells: a row (top and side view) per hit, a column per controller (order of first use)."""
    hits = list(dict.fromkeys((s.info["session"], s.info["rally"], s.info["hit"]) for s in scenes))
    controllers = list(dict.fromkeys(s.info["controller"] for s in scenes))
    legend_columns = min(len(LEGEND), 2 * len(controllers))  # one line of legend from 4 columns on
    legend_rows = -(-len(LEGEND) // legend_columns)
    size = (4.4 * len(controllers) + 0.4, 4.6 * len(hits) + 0.4 + 0.22 * legend_rows)
    fig, axes = plt.subplots(2 * len(hits), len(controllers), figsize=size, squeeze=False, sharex=True)
    # margins in inches, so that the row labels and the legend fit whatever the grid
    fig.subplots_adjust(left=0.75 / size[0], right=1 - 0.1 / size[0], top=1 - 0.35 / size[1],
                        bottom=(0.45 + 0.22 * legend_rows) / size[1], hspace=0.1, wspace=0.15)
    for scene in scenes:
        info = scene.info
        row = 2 * hits.index((info["session"], info["rally"], info["hit"]))
        col = controllers.index(info["controller"])
        draw_cell(axes[row, col], axes[row + 1, col], scene, robot, visuals)
        if col == 0:
            middle = (axes[row, 0].get_position().y1 + axes[row + 1, 0].get_position().y0) / 2
            fig.text(0.08 / size[0], middle, f"{info['session']} rally {info['rally']} hit {info['hit']}\n"
                     f"{info['hitter']} hitter, {info['region']}", rotation=90, va="center", fontsize=9)
    for ax in axes[:-1].ravel():
        ax.set_xlabel("")  # y is labelled under the last row only
    fig.legend(handles=LEGEND, loc="lower center", ncol=legend_columns, fontsize=8, frameon=False)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
