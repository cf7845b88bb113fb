"""Ball-detection QA: one camera's detector decisions and its multi-view ball as a contact sheet a person
checks in a minute.

Method. The detector's candidates table (schemas.BALL_CANDIDATES: every blob it weighed, kept or refused and
why) and the camera's ball after the cameras agree (interim/ball_views, schemas.DETECTIONS: the ball the
pipeline uses, written by triangulation: its detection kept where the views agree with it, dropped where
they agree elsewhere, or filled with one of its candidates that they agree with) sort the frames into kinds:
where the multi-view ball is not the detection (filled: a view where none was kept; dropped: a detection
without a view; moved: both, at different pixels, i.e. another candidate); frames with a kept detection; for
each refusal reason, frames with a candidate refused for it (reasons by how many candidates they refused,
the most frequent first); frames with candidates but no detection. The three differences go first: they are
the rarest (the default run's s02, four cameras of 11,948 frames: filled 106-254, dropped 11-43, moved 0-101
frames a camera) and what a lab checks its cameras for, and a frame goes to the first kind that takes it, so
a filled frame (also a frame of a refusal and of no detection) is titled filled. Tiles go to the kinds in
turn, one each per round, so every kind present gets a tile before any gets a second (all of them when the
kinds are at most the tiles, save a kind whose every frame an earlier kind took that round), and within a
kind the frames are taken in a spread order (the middle, then the quarters, then the eighths, ...), so that
any number of them covers the stream evenly. A frame is shown once, with all of its candidates. Each tile is
a square crop of the frame around what put it there (the kept candidate, the refused one, the multi-view
ball of a filled frame; a moved frame's crop is about the midpoint of the detection and the view, grown to
hold both with their marks), of CROP_DIAMETERS ball diameters (at least 1/MIN_CROP_SHARE of the image's
width), scaled to TILE_PX so a 4 px ball of a 480x360 stream shows 13 px wide: kept candidates circled
green, refused ones red with their reason, the multi-view ball marked on every tile with a cyan X (open in
the middle, so the ball and its circle stay visible; diagonal, so it keeps off a reason's text); the tile
titled with the frame's time on the stream (s from its first frame) and its kind. A summary band on top
counts the stream's frames, the frames with candidates, the detections, the frames with candidates but none
kept, the refusals by reason, the frames with a multi-view ball and the filled, dropped and moved frames,
with the legend (a dropped ball: a green circle without an X).

Inputs: the candidates table, the camera's ball_views table, the camera stream (any reader of
io.camera_streams) and its frame times.
Cost: only the chosen frames are decoded (at most TILE_ROWS x TILE_COLUMNS = 24); the stream is still read
up to the last of them (a compressed frame's bytes, not its pixels; a video's frames are decoded by PyAV as
they pass, which its reader cannot skip). Measured on the tiny twin's s00 cam0 (8,442 frames of 480x360, a
316 MB MCAP, in the page cache; candidates = its colour detections, and those with a refused static box in
every third frame and every tenth detection refused off_track): the sheet 0.50-0.75 s (ball_qa_sheet, the
last chosen frame at 0.76-0.92 of the stream), the whole job 1.05-2.05 s wall, 0.9-1.1 s of CPU with its
imports (`python workflow/scripts/stage.py report_ball_qa --input stream=... candidates=... --output
figure=... --params ...`, four runs). The multi-view ball costs ~0.01 s: on the default run's s02 cam0 and
cam1 (11,948 frames of 480x360, 478 MB MCAPs, ~87,000 candidates, 2 cores shared with 3 other jobs)
view_changes took 9-12 ms (choose_tiles, which calls it, 60-85 ms); the sheet 0.63-1.95 s (three runs each,
the last chosen frame at 0.72-0.75 of the stream); the whole job (the command above with
ball_views=interim/ball_views/s02) 2.35-2.56 s wall and 0.98-1.02 s of user CPU against 2.47-2.60 s and
0.96-1.03 s without it (its commit's parent, same inputs, runs interleaved): within the runs' spread. The
default run's 16 cameras (4 sessions of the same 12 rallies): ~15-18 s of CPU, ~1 % of the run's 1,300-1,500
s. A video costs its decode up to the last chosen frame: an H.264 1280x720 clip (900 frames of a noise image
with a moving disc, PyAV's libx264) passed through open_camera_stream at 420-535 frames/s, so ~40 s for 10
minutes at 30 fps.

Failure modes: a frame that does not decode is shown as a grey tile with the decoder's reason; a chosen time
missing from the stream (a candidates table of another recording) leaves its tile out, with a warning; a
ball_views table of another run may name a filled view at a frame without candidates: its tile shows the
view alone; candidates far apart in one frame (a refused box beside the ball) show on the tile of each only
where they fall inside its crop; a moved view far across the image makes its crop the image's height, its
balls a few px (farther than that, one of the two falls off the tile); more kinds than tiles leave the last
kinds (no detection, then the rarest refusal reasons) without a tile of their own (the summary band still
counts them). The kinds compare pixels: a view within SAME_PX of the detection is it (views copy their
detection's or candidate's pixel).
"""

import logging
import textwrap
from collections.abc import Iterator
from typing import NamedTuple

import cv2
import numpy as np
import pandas as pd

log = logging.getLogger(__name__)

TILE_ROWS, TILE_COLUMNS = 4, 6  # 24 tiles: a sheet read in a minute
TILE_PX = 192  # a tile's side; 6 tiles make a 1152 px wide sheet
TITLE_PX = 18  # the title bar above each tile
CROP_DIAMETERS = 12  # a crop's side in ball diameters: the ball and what refused candidates stand beside
MIN_CROP_SHARE = 8  # a crop at least width / 8 px: 60 px of a 480 px stream (3.2x), 160 of a 1280 (1.2x)
MARK_REACH_PX = 16  # a tile's marks beyond a ball's edge: the X's arms to its circle's radius (>= 6) + 10
KEPT_BGR, REFUSED_BGR, VIEW_BGR = (0, 255, 0), (40, 40, 255), (255, 255, 0)  # green, red, cyan
KEPT, NO_DETECTION = "kept", "no detection"
FILLED, DROPPED, MOVED = "filled", "dropped", "moved"  # the multi-view ball where it is not the detection
SAME_PX = 0.01  # a view copies its detection's or candidate's pixel: within this it is that one
FONT = cv2.FONT_HERSHEY_SIMPLEX


class Focus(NamedTuple):
    """What a tile's crop is around: a point (px), the area of the blob there (px^2), and a span (px)
    that the crop must also show around it along either axis (two points that far apart: a moved ball)."""
    u: float
    v: float
    area_px: float
    span_px: float = 0.0


def view_changes(candidates: pd.DataFrame, views: pd.DataFrame) -> list[tuple[str, np.ndarray]]:
    """(kind, its frames' times ascending) for filled, dropped and moved: the frames where the camera's
    multi-view ball (views: DETECTIONS, ball_views) is there but its own detection (the kept candidate)
    is not, the detection is there but the view is not, or both are there at different pixels."""
    own = candidates.loc[candidates["kept"].to_numpy(bool), ["time_ns", "u", "v"]]
    seen = views.loc[views["detected"].to_numpy(bool), ["time_ns", "u", "v"]]
    both = seen.merge(own, on="time_ns", how="outer", suffixes=("", "_own"))
    in_view, detected = both["u"].notna().to_numpy(), both["u_own"].notna().to_numpy()
    apart = np.hypot(both["u"] - both["u_own"], both["v"] - both["v_own"]).to_numpy() > SAME_PX  # NaN: not
    times = both["time_ns"].to_numpy(np.int64)
    return [(FILLED, np.unique(times[in_view & ~detected])), (DROPPED, np.unique(times[~in_view & detected])),
            (MOVED, np.unique(times[apart]))]


def decision_kinds(candidates: pd.DataFrame, views: pd.DataFrame) -> list[tuple[str, np.ndarray]]:
    """(kind, its frames' times ascending) of every kind of decision in the tables, in the order tiles go
    to them: where the multi-view ball differs from the detection (filled, dropped, moved: the rarest and
    what a lab checks its cameras for, first so that their frames are titled with it); kept; each refusal
    reason, the most frequent (in candidates) first; no detection."""
    kept = candidates["kept"].to_numpy(bool)
    refused = candidates[~kept]
    detections = np.unique(candidates.loc[kept, "time_ns"].to_numpy(np.int64))
    kinds = [*view_changes(candidates, views), (KEPT, detections)]
    counts = refused["reason"].value_counts()
    for reason in sorted(counts.index, key=lambda r: (-counts[r], r)):
        times = refused.loc[refused["reason"] == reason, "time_ns"].to_numpy(np.int64)
        kinds.append((reason, np.unique(times)))
    with_candidates = np.unique(candidates["time_ns"].to_numpy(np.int64))
    kinds.append((NO_DETECTION, np.setdiff1d(with_candidates, detections, assume_unique=True)))
    return [(kind, times) for kind, times in kinds if len(times)]


def spread_order(n: int) -> Iterator[int]:
    """Every index of range(n) once, in an order whose every prefix is spread over the range: the middle,
    then the quarters, the eighths, ... (lazy: a few tiles' picks cost a few steps, not n)."""
    seen, parts = set(), 1
    while len(seen) < n:
        for j in range(parts):
            index = min(int((j + 0.5) * n / parts), n - 1)
            if index not in seen:
                seen.add(index)
                yield index
        parts *= 2


def _spread(times: np.ndarray) -> Iterator[int]:
    return (int(times[i]) for i in spread_order(len(times)))


def choose_tiles(candidates: pd.DataFrame, views: pd.DataFrame, n_tiles: int) -> pd.DataFrame:
    """The frames to show (time_ns, kind), at most n_tiles, ordered by kind (decision_kinds' order) and
    time: kinds take a frame each in turn, each its next frame in spread order not already shown."""
    kinds = decision_kinds(candidates, views)
    picks = {kind: _spread(times) for kind, times in kinds}
    chosen: dict[int, str] = {}
    while picks and len(chosen) < n_tiles:
        for kind in list(picks):
            pick = next((t for t in picks[kind] if t not in chosen), None)
            if pick is None:
                del picks[kind]
            elif len(chosen) < n_tiles:
                chosen[pick] = kind
    order = {kind: k for k, (kind, _) in enumerate(kinds)}
    tiles = pd.DataFrame({"time_ns": np.array(list(chosen), np.int64), "kind": list(chosen.values())})
    tiles["rank"] = tiles["kind"].map(order)
    return tiles.sort_values(["rank", "time_ns"]).drop(columns="rank").reset_index(drop=True)


def _diameter_px(area_px: float) -> float:
    return 2.0 * np.sqrt(max(float(area_px), 1.0) / np.pi)


def crop_square(u: float, v: float, area_px: float, width: int, height: int,
                span_px: float = 0.0) -> tuple[int, int, int]:
    """(x0, y0, side) of the square crop around a candidate at (u, v) px of a width x height image: side
    CROP_DIAMETERS of its diameters, at least width / MIN_CROP_SHARE and what shows two balls span_px apart
    about (u, v) with their marks (each ball's edge MARK_REACH_PX from the tile's: (span_px + a diameter) /
    (1 - 2 MARK_REACH_PX / TILE_PX)), at most the image; shifted inside."""
    diameter = _diameter_px(area_px)
    both = (span_px + diameter) / (1 - 2 * MARK_REACH_PX / TILE_PX)
    side = max(CROP_DIAMETERS * diameter, width / MIN_CROP_SHARE, both)
    side = int(round(min(side, width, height)))
    x0 = int(np.clip(round(u - side / 2), 0, width - side))
    y0 = int(np.clip(round(v - side / 2), 0, height - side))
    return x0, y0, side


def tile_position(uv: np.ndarray, x0: int, y0: int, side: int) -> np.ndarray:
    """Pixel (u, v) of the image at its place on the tile of the crop (x0, y0, side): pixel centres map
    as cv2.resize's do (centre of pixel i at i + 0.5 of the crop's extent)."""
    scale = TILE_PX / side
    return (np.asarray(uv, float) - (x0, y0) + 0.5) * scale - 0.5


def _text(image: np.ndarray, text: str, origin, colour, size: float = 0.4) -> None:
    """Text with a dark outline, readable on any background."""
    cv2.putText(image, text, origin, FONT, size, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(image, text, origin, FONT, size, colour, 1, cv2.LINE_AA)


def _radius(area_px: float, scale: float) -> int:
    """A circle's radius on the tile around a blob of area_px: 4 px outside it, at least 6 px."""
    return max(6, int(round(_diameter_px(area_px) / 2 * scale)) + 4)


def _on_tile(centre: np.ndarray) -> bool:
    return bool((-TILE_PX / 2 < centre).all() and (centre < 1.5 * TILE_PX).all())


def draw_view(body: np.ndarray, centre: np.ndarray, radius: int) -> None:
    """The multi-view ball's marker: a cyan X with an open middle (its arms from radius + 2 to radius + 10
    px from the centre), so the ball and its circle beneath stay visible; diagonal, so it keeps off the
    reason written level with a refused candidate's centre (an upright cross hid its first letters)."""
    x, y = centre
    steps = np.array([radius + 2, radius + MARK_REACH_PX - 6]) / np.sqrt(2)  # the circle: the ball + 4, >= 6
    for dx, dy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        near, far = np.rint(np.column_stack([x + dx * steps, y + dy * steps])).astype(int).tolist()
        cv2.line(body, near, far, VIEW_BGR, 2, cv2.LINE_AA)


def draw_tile(image: np.ndarray | None, rows: pd.DataFrame, view: pd.Series | None, focus: Focus,
              title: str, reason: str = "") -> np.ndarray:
    """A titled tile (TITLE_PX + TILE_PX) x TILE_PX: the crop of the BGR image around `focus` scaled up,
    each of the frame's candidates (`rows`) inside it circled (kept green, refused red with its reason),
    the multi-view ball (`view`: u, v, area_px; None where there is none) marked with a cyan X; an
    image that did not decode (None) gives a grey tile with `reason`."""
    tile = np.zeros((TITLE_PX + TILE_PX, TILE_PX, 3), np.uint8)
    _text(tile, title, (4, TITLE_PX - 5), (255, 255, 255))
    body = tile[TITLE_PX:]
    if image is None:
        body[:] = 64
        for k, line in enumerate(textwrap.wrap(f"no image: {reason}", 30)[:6]):
            _text(body, line, (4, 20 + 16 * k), (255, 255, 255))
        return tile
    height, width = image.shape[:2]
    x0, y0, side = crop_square(focus.u, focus.v, focus.area_px, width, height, focus.span_px)
    crop = image[y0:y0 + side, x0:x0 + side]
    body[:] = cv2.resize(crop, (TILE_PX, TILE_PX), interpolation=cv2.INTER_LINEAR)
    scale = TILE_PX / side
    for row in rows.itertuples(index=False):
        centre = tile_position((row.u, row.v), x0, y0, side)
        if not _on_tile(centre):
            continue  # far outside the crop: nothing of it would show
        radius = _radius(row.area_px, scale)
        point = tuple(int(round(c)) for c in centre)
        colour = KEPT_BGR if row.kept else REFUSED_BGR
        cv2.circle(body, point, radius, colour, 2, cv2.LINE_AA)
        if not row.kept:  # the reason right of the circle, or left where it would run off the tile
            text_px = cv2.getTextSize(str(row.reason), FONT, 0.4, 1)[0][0]
            left = point[0] + radius + 2 + text_px > TILE_PX
            x = point[0] - radius - 2 - text_px if left else point[0] + radius + 2
            _text(body, str(row.reason), (x, point[1] + 4), colour)
    if view is not None:
        centre = tile_position((view["u"], view["v"]), x0, y0, side)
        if _on_tile(centre):
            draw_view(body, centre, _radius(view["area_px"], scale))
    return tile


def summary_lines(candidates: pd.DataFrame, views: pd.DataFrame, n_frames: int, label: str,
                  width_px: int) -> list[str]:
    """The sheet's summary: frames, frames with candidates, detections, frames with candidates but none
    kept, refusals by reason (most frequent first), the multi-view ball's frames and where it differs
    from the detection (filled, dropped, moved), wrapped to width_px."""
    kept = candidates["kept"].to_numpy(bool)
    with_candidates = candidates["time_ns"].nunique()
    detections = candidates.loc[kept, "time_ns"].nunique()
    refusals = candidates.loc[~kept, "reason"].value_counts()
    refused = ", ".join(f"{reason} {count:,}" for reason, count in refusals.items()) or "none"
    legend = {FILLED: "a candidate, none kept", DROPPED: "no X", MOVED: "another candidate"}
    changes = view_changes(candidates, views)
    differ = ", ".join(f"{len(times):,} {kind} ({legend[kind]})" for kind, times in changes)
    text = (f"{label}: {n_frames:,} frames, {with_candidates:,} with candidates, {detections:,} with a "
            f"detection (green), {with_candidates - detections:,} with candidates but none kept; "
            f"{(~kept).sum():,} candidates refused (red, with the reason): {refused}; the multi-view ball "
            f"(cyan X) in {views['detected'].sum():,} frames; not the detection in {differ}")
    char_px = cv2.getTextSize(text, FONT, 0.5, 1)[0][0] / len(text)  # the text's mean, not the widest
    return textwrap.wrap(text, max(20, int(width_px / char_px) - 2))


def contact_sheet(tiles: list[np.ndarray], summary: list[str]) -> np.ndarray:
    """The tiles in rows of TILE_COLUMNS under the summary band (a band alone where there are none)."""
    band = np.zeros((10 + 20 * len(summary), TILE_COLUMNS * TILE_PX, 3), np.uint8)
    for k, line in enumerate(summary):
        cv2.putText(band, line, (6, 22 + 20 * k), FONT, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    rows = []
    for start in range(0, len(tiles), TILE_COLUMNS):
        row = tiles[start:start + TILE_COLUMNS]
        row += [np.zeros_like(row[0])] * (TILE_COLUMNS - len(row))
        rows.append(np.hstack(row))
    return np.vstack([band, *rows])


def _focus(rows: pd.DataFrame, view: pd.Series | None, kind: str) -> Focus:
    """What put the frame on the sheet: the multi-view ball (filled), it and the detection (moved: the
    crop about their midpoint shows both), the kept candidate (kept, dropped), the best scored of the
    reason's, or (no detection) the best scored of all."""
    if kind == FILLED:
        return Focus(view["u"], view["v"], view["area_px"])
    if kind in (KEPT, DROPPED, MOVED):
        mine = rows[rows["kept"]]
    elif kind == NO_DETECTION:
        mine = rows
    else:
        mine = rows[~rows["kept"] & (rows["reason"] == kind)]
    best = mine.iloc[int(np.argmax(np.nan_to_num(mine["score"].to_numpy(float), nan=-np.inf)))]
    if kind == MOVED:
        du, dv = view["u"] - best["u"], view["v"] - best["v"]
        return Focus(best["u"] + du / 2, best["v"] + dv / 2, best["area_px"], max(abs(du), abs(dv)))
    return Focus(best["u"], best["v"], best["area_px"])


def ball_qa_sheet(frames, frame_times: np.ndarray, candidates: pd.DataFrame, views: pd.DataFrame,
                  label: str) -> np.ndarray:
    """The QA contact sheet of one camera: its stream (Frame iterator, time order), the stream's frame
    times (ns), its candidates table and its multi-view ball (DETECTIONS, one row a frame). Decodes only
    the chosen frames and stops after the last."""
    chosen = choose_tiles(candidates, views, TILE_ROWS * TILE_COLUMNS)
    wanted = dict(zip(chosen["time_ns"].tolist(), chosen["kind"], strict=True))
    images: dict[int, tuple[np.ndarray | None, str]] = {}
    for frame in frames:
        if frame.time_ns in wanted:
            images[frame.time_ns] = frame.decode()
            if len(images) == len(wanted):
                break
    missing = sorted(set(wanted) - set(images))
    if missing:
        log.warning("%s: %d chosen frames are not in the stream (first at %d ns); left out of the sheet",
                    label, len(missing), missing[0])
    seen = views[views["detected"].to_numpy(bool) & views["time_ns"].isin(wanted)].set_index("time_ns")
    tiles = []
    for time_ns, kind in wanted.items():
        if time_ns not in images:
            continue
        (image, reason), view = images[time_ns], seen.loc[time_ns] if time_ns in seen.index else None
        rows = candidates[candidates["time_ns"] == time_ns]  # none: a filled view of another run's table
        title = f"{(time_ns - frame_times[0]) / 1e9:.2f} s {kind}"
        tiles.append(draw_tile(image, rows, view, _focus(rows, view, kind), title, reason))
    summary = summary_lines(candidates, views, len(frame_times), label, TILE_COLUMNS * TILE_PX)
    return contact_sheet(tiles, summary)
