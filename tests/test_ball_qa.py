"""Ball-detection QA sheet: which frames it shows (every kind of decision and every way the multi-view ball
differs from the detection, spread over the stream, never more tiles than asked, only frames of the stream),
where it draws (a kept candidate circled green, the multi-view ball's cyan X, at their places on the
tile), and the stage on a tiny MCAP stream written with pingpong's own writer, with a ball_views table."""

import cv2
import numpy as np
import pandas as pd
from conftest import TINY_RUN
from hypothesis import given
from hypothesis import strategies as st

from pingpong.common.artifacts import Provenance, read_table, write_table
from pingpong.common.script import Named, StageContext
from pingpong.io.camera_streams import CameraFrame
from pingpong.io.mcap_io import CameraStreamWriter
from pingpong.perception.schemas import BALL_CANDIDATES, DETECTIONS
from pingpong.reports import ball_qa
from pingpong.reports.ball_qa import (
    DROPPED,
    FILLED,
    KEPT,
    KEPT_BGR,
    MOVED,
    NO_DETECTION,
    REFUSED_BGR,
    TILE_COLUMNS,
    TILE_PX,
    TITLE_PX,
    VIEW_BGR,
    Focus,
    ball_qa_sheet,
    choose_tiles,
    crop_square,
    draw_tile,
    spread_order,
    tile_position,
    view_changes,
)
from pingpong.stages import report_ball_qa

FRAME_NS = 10_000_000  # 100 Hz, the twin's camera clock
FIRST_NS = 1_000_000_000


def candidate(frame, u, v, kept, reason, area=20.0, score=1.0, first_ns=0):
    return {"time_ns": first_ns + frame * FRAME_NS, "u": u, "v": v, "area_px": area, "score": score,
            "kept": kept, "reason": reason}


def lab_table() -> pd.DataFrame:
    """100 frames: the ball kept in frames 0-59, a static box refused in every frame, a held ball refused as
    slow in 60-69, one size refusal in frame 80; frames 60-99 have candidates but no detection."""
    rows = [candidate(f, 100 + f, 200, True, KEPT) for f in range(60)]
    rows += [candidate(f, 400, 300, False, "static", area=80, score=0.2) for f in range(100)]
    rows += [candidate(f, 250, 100 + f, False, "slow", score=0.5) for f in range(60, 70)]
    rows += [candidate(80, 30, 30, False, "size", area=400, score=0.1)]
    return pd.DataFrame(rows)


def views_of(candidates: pd.DataFrame, n_frames: int, pick=lambda frame, rows: rows[rows["kept"]]):
    """A DETECTIONS table of n_frames frames: each frame's multi-view ball the candidate `pick` returns of
    the frame's candidates (at most one row; the kept one unless told), none where it returns none."""
    rows = []
    for frame in range(n_frames):
        time_ns = frame * FRAME_NS
        chosen = pick(frame, candidates[candidates["time_ns"] == time_ns])
        u, v, area = chosen[["u", "v", "area_px"]].iloc[0] if len(chosen) else (np.nan, np.nan, 0.0)
        rows.append({"time_ns": time_ns, "u": u, "v": v, "area_px": area, "detected": bool(len(chosen)),
                     "decode_ok": True})
    return pd.DataFrame(rows, columns=list(DETECTIONS.columns))


def lab_views(table: pd.DataFrame) -> pd.DataFrame:
    """The lab's multi-view ball: the detection, but dropped in frames 10-11, moved to the static box in 20,
    filled with the slow (held) ball in 62-64."""
    def pick(frame, rows):
        if frame in (10, 11):
            return rows.iloc[:0]
        if frame == 20 or 62 <= frame <= 64:
            return rows[rows["reason"] == ("static" if frame == 20 else "slow")]
        return rows[rows["kept"]]
    return views_of(table, 100, pick)


def test_spread_order_is_every_index_once_and_its_prefixes_spread():
    for n in (1, 2, 7, 100):
        order = list(spread_order(n))
        assert sorted(order) == list(range(n))
    assert list(spread_order(100))[:7] == [50, 25, 75, 12, 37, 62, 87]  # the middle, quarters, eighths


def test_every_kind_gets_tiles_spread_over_its_frames():
    table = lab_table()
    tiles = choose_tiles(table, lab_views(table), 24)
    assert len(tiles) == 24 and tiles["time_ns"].is_unique
    # kinds in the sheet's order: the multi-view ball's differences, kept, refusals by frequency (static
    # 100, slow 10, size 1), no detection
    assert list(dict.fromkeys(tiles["kind"])) == [FILLED, DROPPED, MOVED, KEPT, "static", "slow", "size",
                                                  NO_DETECTION]
    frames = lambda kind: set(tiles.loc[tiles["kind"] == kind, "time_ns"] // FRAME_NS)  # noqa: E731
    assert frames(FILLED) == {62, 63, 64} and frames(DROPPED) == {10, 11} and frames(MOVED) == {20}
    assert (tiles["kind"] == "size").sum() == 1 and 80 * FRAME_NS in set(tiles["time_ns"])
    kept = tiles.loc[tiles["kind"] == KEPT, "time_ns"] // FRAME_NS
    # over the kept frames 0-59 (10, 11 dropped): five tiles, the middle, the quarters (15, 45), two eighths
    assert kept.is_monotonic_increasing and kept.min() < 15 and kept.max() >= 45
    shown = table[table["time_ns"].isin(tiles.loc[tiles["kind"] == NO_DETECTION, "time_ns"])]
    assert not shown["kept"].any()
    assert len(choose_tiles(table, lab_views(table), 3)) == 3
    without_changes = choose_tiles(table, views_of(table, 100), 24)  # the views are the detections
    assert not without_changes["kind"].isin([FILLED, DROPPED, MOVED]).any()


@st.composite
def candidate_tables(draw):
    """Up to 40 frames with 0-4 candidates each, at most one kept, reasons from six names; and their
    multi-view ball: each frame's kept candidate, none, or another of its candidates."""
    rows = []
    n_frames = draw(st.integers(1, 40))
    for frame in range(n_frames):
        n = draw(st.integers(0, 4))
        kept_at = draw(st.integers(-1, n - 1)) if n else -1
        for k in range(n):
            reason = KEPT if k == kept_at else draw(st.sampled_from(["static", "slow", "off_track", "colour",
                                                                     "size", "lone"]))
            u, v = draw(st.floats(0, 479)), draw(st.floats(0, 359))
            rows.append(candidate(frame, u, v, k == kept_at, reason, score=draw(st.floats(0, 1))))
    table = pd.DataFrame(rows, columns=list(BALL_CANDIDATES.columns))
    view_at = draw(st.lists(st.integers(-2, 3), min_size=n_frames, max_size=n_frames))  # -2: the kept one

    def pick(frame, rows):
        return rows[rows["kept"]] if view_at[frame] == -2 else rows.iloc[view_at[frame]:view_at[frame] + 1]
    return table, views_of(table, n_frames, pick)


@given(tables=candidate_tables(), n_tiles=st.integers(1, 30))
def test_selection_shows_every_reason_never_exceeds_the_tiles_and_only_stream_frames(tables, n_tiles):
    table, views = tables
    tiles = choose_tiles(table, views, n_tiles)
    frames_with_candidates = table["time_ns"].nunique()
    assert len(tiles) == min(n_tiles, frames_with_candidates) and tiles["time_ns"].is_unique
    assert set(tiles["time_ns"]) <= set(table["time_ns"])  # the candidates' frames: frames of the stream
    shown = table[table["time_ns"].isin(tiles["time_ns"])]
    kinds = ball_qa.decision_kinds(table, views)
    changes = dict(view_changes(table, views))
    if len(kinds) <= n_tiles:
        assert set(shown.loc[~shown["kept"], "reason"]) == set(table.loc[~table["kept"], "reason"])
        assert shown["kept"].any() == table["kept"].any()
        no_detection = lambda t: (~t.groupby("time_ns")["kept"].any()).any()  # noqa: E731
        assert no_detection(shown) == no_detection(table)
        for kind, times in changes.items():  # a frame of each way the views differ, titled with it
            assert len(times) == 0 or kind in set(tiles["kind"]), kind
    view = views.set_index("time_ns")
    for time_ns, kind in tiles.itertuples(index=False):  # each frame shows the decision it stands for
        rows = table[table["time_ns"] == time_ns]
        if kind in changes:
            assert time_ns in changes[kind]
            own = rows[rows["kept"]]
            assert view.loc[time_ns, "detected"] == (kind != DROPPED) and len(own) == (kind != FILLED)
            if kind == MOVED:
                assert (own["u"].iloc[0], own["v"].iloc[0]) != tuple(view.loc[time_ns, ["u", "v"]])
        elif kind == KEPT:
            assert rows["kept"].any()
        elif kind == NO_DETECTION:
            assert not rows["kept"].any()
        else:
            assert (~rows["kept"] & (rows["reason"] == kind)).any()


def _near(tile, colour, centre, radius):
    """Whether the tile has pixels of `colour` (anti-aliased: near it) within radius px of centre."""
    v, u = np.indices(tile.shape[:2])
    within = np.hypot(u - centre[0], v - centre[1]) <= radius
    return bool((np.abs(tile[within].astype(int) - colour).sum(axis=-1) < 120).any())


def test_a_kept_candidate_is_circled_green_where_its_centre_falls_on_the_tile():
    image = np.full((360, 480, 3), 90, np.uint8)
    rows = pd.DataFrame([candidate(0, 123.4, 77.8, True, KEPT), candidate(0, 140.0, 90.0, False, "slow")])
    tile = draw_tile(image, rows, None, Focus(123.4, 77.8, 20.0), "0.00 s kept")
    assert tile.shape == (TITLE_PX + TILE_PX, TILE_PX, 3)
    body = tile[TITLE_PX:]
    x0, y0, side = crop_square(123.4, 77.8, 20.0, 480, 360)
    assert side == 61  # the larger of 12 diameters of a 20 px blob (60.55 px) and width / 8 (60), rounded
    kept_at = tile_position((123.4, 77.8), x0, y0, side)
    radius = int(round(2 * np.sqrt(20 / np.pi) / 2 * TILE_PX / side)) + 4
    assert _near(body, KEPT_BGR, kept_at, radius + 2) and not _near(body, KEPT_BGR, kept_at, radius - 4)
    assert _near(body, REFUSED_BGR, tile_position((140.0, 90.0), x0, y0, side), radius + 2)
    refused_only = draw_tile(image, rows.iloc[1:], None, Focus(140.0, 90.0, 20.0), "0.00 s slow")
    assert not _near(refused_only, KEPT_BGR, (TILE_PX / 2, TILE_PX / 2 + TITLE_PX), TILE_PX)
    assert not _near(tile, VIEW_BGR, (TILE_PX / 2, TILE_PX / 2 + TITLE_PX), TILE_PX)  # no view: no X


def _cyan(body):
    """The (u, v) tile pixels of the cyan X: near cyan and unlike the grey image and the circles."""
    return np.argwhere(np.abs(body.astype(int) - VIEW_BGR).sum(axis=-1) < 200)[:, ::-1]


def test_the_multi_view_ball_is_a_cyan_x_centred_on_its_pixel_with_the_ball_left_open():
    """A view at the refused candidate (a moved ball): the X's pixels centre on the view's place on the
    tile within 1 px (its arms are alike), none within the circle's radius (the ball stays visible)."""
    image = np.full((360, 480, 3), 90, np.uint8)
    rows = pd.DataFrame([candidate(0, 123.4, 77.8, True, KEPT), candidate(0, 140.0, 90.0, False, "slow")])
    view = rows.iloc[1][["u", "v", "area_px"]]
    body = draw_tile(image, rows, view, Focus(123.4, 77.8, 20.0), "0.00 s moved")[TITLE_PX:]
    x0, y0, side = crop_square(123.4, 77.8, 20.0, 480, 360)
    centre = tile_position((140.0, 90.0), x0, y0, side)
    cross = _cyan(body)
    assert len(cross) > 40 and np.abs(cross.mean(axis=0) - centre).max() < 1.0
    radius = int(round(2 * np.sqrt(20 / np.pi) / 2 * TILE_PX / side)) + 4
    assert np.hypot(*(cross - centre).T).min() > radius - 1 and not _near(body, VIEW_BGR, centre, radius - 1)


def test_a_moved_ball_tile_shows_both_the_detection_and_the_view():
    """A view 150 px from the detection of a 480 px frame (farther than a crop of width / 8): the moved tile's
    crop grows to hold both, the detection circled green and the view marked with the cyan X."""
    image = np.full((360, 480, 3), 90, np.uint8)
    rows = pd.DataFrame([candidate(0, 100.0, 100.0, True, KEPT), candidate(0, 250.0, 160.0, False, "static")])
    views = views_of(rows, 1, lambda frame, r: r[~r["kept"]])
    focus = ball_qa._focus(rows, views.iloc[0], MOVED)
    body = draw_tile(image, rows, views.iloc[0], focus, "0.00 s moved")[TITLE_PX:]
    x0, y0, side = crop_square(*focus[:3], 480, 360, focus.span_px)
    assert side == round((150 + 2 * np.sqrt(20 / np.pi)) / (1 - 32 / TILE_PX))  # span, ball, 16 px marks
    for u, v in ((100.0, 100.0), (250.0, 160.0)):
        assert (0 <= tile_position((u, v), x0, y0, side)).all() and (tile_position((u, v), x0, y0, side)
                                                                      < TILE_PX).all()
    assert _near(body, KEPT_BGR, tile_position((100.0, 100.0), x0, y0, side), 12)
    assert np.abs(_cyan(body).mean(axis=0) - tile_position((250.0, 160.0), x0, y0, side)).max() < 1.0


def test_a_crop_at_the_image_edge_stays_inside_and_the_point_keeps_its_place():
    x0, y0, side = crop_square(2.0, 355.0, 20.0, 480, 360)
    assert (x0, y0) == (0, 360 - side)
    u, v = tile_position((2.0, 355.0), x0, y0, side)
    assert abs(u - (2.5 * TILE_PX / side - 0.5)) < 1e-9 and 0 < v < TILE_PX


class CountingFrame(CameraFrame):
    decoded: list = []

    def decode(self, reduction=1):
        CountingFrame.decoded.append(self.time_ns)
        return super().decode(reduction)


def test_the_sheet_decodes_only_the_chosen_frames_and_stops_after_the_last():
    table = lab_table()
    jpeg = cv2.imencode(".jpg", np.full((360, 480, 3), 90, np.uint8))[1].tobytes()
    times = np.arange(120, dtype=np.int64) * FRAME_NS  # 20 frames past the candidates' last
    passed = []

    def frames():
        for t in times:
            passed.append(int(t))
            yield CountingFrame(int(t), jpeg)

    CountingFrame.decoded = []
    views = lab_views(table)
    sheet = ball_qa_sheet(frames(), times, table, views, "s00 cam0")
    chosen = choose_tiles(table, views, 24)
    assert sorted(CountingFrame.decoded) == sorted(chosen["time_ns"])
    assert passed[-1] == chosen["time_ns"].max()  # the stream is left after the last chosen frame
    band = sheet.shape[0] - 4 * (TITLE_PX + TILE_PX)  # 4 rows of tiles under the summary band
    assert sheet.shape[1] == TILE_COLUMNS * TILE_PX and 30 <= band < 90


def test_the_stage_writes_the_sheet_of_a_tiny_stream(tmp_path):
    """20 frames of an orange ball crossing a grey room beside a static box, refused off_track in every
    fourth frame, where the multi-view ball fills it: the sheet has a tile per frame with candidates
    (20 < 24), 4 rows of 6, its filled tiles first with the ball marked by the cyan X, its kept tiles the
    ball circled green."""
    stream, candidates = tmp_path / "cam0.mcap", tmp_path / "cam0.parquet"
    (tmp_path / "ball_views").mkdir()
    rows = []
    with CameraStreamWriter(stream, 0, "cam0") as writer:
        for f in range(20):
            image = np.full((360, 480, 3), 90, np.uint8)
            cv2.rectangle(image, (380, 280), (420, 320), (40, 70, 110), -1)
            u, v = 60.0 + 15 * f, 120.0 + 4 * f
            cv2.circle(image, (int(u), int(v)), 3, (0, 120, 255), -1)
            writer.add(FIRST_NS + f * FRAME_NS, cv2.imencode(".jpg", image)[1].tobytes())
            rows += [candidate(f, u, v, f % 4 != 3, KEPT if f % 4 != 3 else "off_track", first_ns=FIRST_NS),
                     candidate(f, 400.0, 300.0, False, "static", area=1600, score=0.1, first_ns=FIRST_NS)]
    write_table(pd.DataFrame(rows), candidates, BALL_CANDIDATES, Provenance("detection"))
    ball = lambda frame, r: r[r["kept"] | (r["reason"] == "off_track")]  # noqa: E731
    shifted = pd.DataFrame(rows).assign(time_ns=lambda t: t["time_ns"] - FIRST_NS)  # views_of: frames from 0
    views = views_of(shifted, 20, ball).assign(time_ns=lambda t: t["time_ns"] + FIRST_NS)
    write_table(views, tmp_path / "ball_views" / "cam0.parquet", DETECTIONS, Provenance("triangulation"))
    out = tmp_path / "ball_qa_s00_cam0.jpg"
    params = {"session": "s00", "cam": "cam0", "strict": True,
              "reading": {"timestamps": None, "start_ns": 0, "topic": None}}
    report_ball_qa.main(StageContext("report_ball_qa", Named(stream=str(stream), timestamps=[],
                                                             candidates=str(candidates),
                                                             ball_views=str(tmp_path / "ball_views")),
                                     Named(figure=str(out)), params, None))
    sheet = cv2.imread(str(out))
    band = sheet.shape[0] - 4 * (TITLE_PX + TILE_PX)
    assert sheet.shape[1] == TILE_COLUMNS * TILE_PX and 30 <= band < 90
    tiles = choose_tiles(pd.DataFrame(rows), views, 24)
    filled = int((tiles["kind"] == FILLED).sum())  # its 5 frames shared with off_track and no detection
    assert len(tiles) == 20 and filled >= 1 and set(tiles["kind"][:filled]) == {FILLED}
    assert tiles["kind"][filled] == KEPT
    for k in (0, filled):  # the first filled frame's tile, the first kept frame's
        body = sheet[band + TITLE_PX:band + TITLE_PX + TILE_PX, k * TILE_PX:(k + 1) * TILE_PX]
        frame = (tiles["time_ns"].iloc[k] - FIRST_NS) // FRAME_NS
        u, v = 60.0 + 15 * frame, 120.0 + 4 * frame
        at = tile_position((u, v), *crop_square(u, v, 20.0, 480, 360))
        assert np.abs(_cyan(body).mean(axis=0) - at).max() < 1.5, k  # the JPEG's blur: 1.5 px
        assert _near(body, KEPT_BGR, at, 20) == (k == filled), k


def test_the_tiny_run_has_a_sheet_for_every_camera(tiny_run):
    """rule all's wiring: a sheet per session and camera, a tile per frame with candidates up to 24."""
    for session in range(TINY_RUN["twin"]["n_sessions"]):
        for cam in range(TINY_RUN["twin"]["n_cameras"]):
            name = f"s{session:02d}/cam{cam}"
            candidates = read_table(tiny_run / f"interim/ball_candidates/{name}.parquet", BALL_CANDIDATES)
            sheet = cv2.imread(str(tiny_run / f"reports/figures/ball_qa_{name.replace('/', '_')}.jpg"))
            tile_rows = -(-min(24, candidates["time_ns"].nunique()) // TILE_COLUMNS)
            assert tile_rows == 4  # the tiny run's streams have far more frames with candidates than tiles
            band = sheet.shape[0] - tile_rows * (TITLE_PX + TILE_PX)
            assert sheet.shape[1] == TILE_COLUMNS * TILE_PX and 30 <= band < 90, name
