"""Ball-detection QA sheet: which frames it shows (every kind of decision, spread over the stream, never more
tiles than asked, only frames of the stream), where it draws (a kept candidate circled green at its place on
the tile), and the stage on a tiny MCAP stream written with pingpong's own writer."""

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
from pingpong.perception.schemas import BALL_CANDIDATES
from pingpong.reports import ball_qa
from pingpong.reports.ball_qa import (
    KEPT,
    KEPT_BGR,
    NO_DETECTION,
    REFUSED_BGR,
    TILE_COLUMNS,
    TILE_PX,
    TITLE_PX,
    ball_qa_sheet,
    choose_tiles,
    crop_square,
    draw_tile,
    spread_order,
    tile_position,
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


def test_spread_order_is_every_index_once_and_its_prefixes_spread():
    for n in (1, 2, 7, 100):
        order = list(spread_order(n))
        assert sorted(order) == list(range(n))
    assert list(spread_order(100))[:7] == [50, 25, 75, 12, 37, 62, 87]  # the middle, quarters, eighths


def test_every_kind_gets_tiles_spread_over_its_frames():
    table = lab_table()
    tiles = choose_tiles(table, 24)
    assert len(tiles) == 24 and tiles["time_ns"].is_unique
    # kinds in the sheet's order: kept, refusals by frequency (static 100, slow 10, size 1), no detection
    assert list(dict.fromkeys(tiles["kind"])) == [KEPT, "static", "slow", "size", NO_DETECTION]
    assert (tiles["kind"] == "size").sum() == 1 and 80 * FRAME_NS in set(tiles["time_ns"])
    kept = tiles.loc[tiles["kind"] == KEPT, "time_ns"] // FRAME_NS
    assert kept.is_monotonic_increasing and kept.min() < 15 and kept.max() > 45  # over the kept frames 0-59
    shown = table[table["time_ns"].isin(tiles.loc[tiles["kind"] == NO_DETECTION, "time_ns"])]
    assert not shown["kept"].any()
    assert len(choose_tiles(table, 3)) == 3


@st.composite
def candidate_tables(draw):
    """Up to 40 frames with 0-4 candidates each, at most one kept, reasons from six names."""
    rows = []
    for frame in range(draw(st.integers(1, 40))):
        n = draw(st.integers(0, 4))
        kept_at = draw(st.integers(-1, n - 1)) if n else -1
        for k in range(n):
            reason = KEPT if k == kept_at else draw(st.sampled_from(["static", "slow", "off_track", "colour",
                                                                     "size", "lone"]))
            u, v = draw(st.floats(0, 479)), draw(st.floats(0, 359))
            rows.append(candidate(frame, u, v, k == kept_at, reason, score=draw(st.floats(0, 1))))
    return pd.DataFrame(rows, columns=list(BALL_CANDIDATES.columns))


@given(table=candidate_tables(), n_tiles=st.integers(1, 30))
def test_selection_shows_every_reason_never_exceeds_the_tiles_and_only_stream_frames(table, n_tiles):
    tiles = choose_tiles(table, n_tiles)
    frames_with_candidates = table["time_ns"].nunique()
    assert len(tiles) == min(n_tiles, frames_with_candidates) and tiles["time_ns"].is_unique
    assert set(tiles["time_ns"]) <= set(table["time_ns"])  # the candidates' frames: frames of the stream
    shown = table[table["time_ns"].isin(tiles["time_ns"])]
    kinds = ball_qa.decision_kinds(table)
    if len(kinds) <= n_tiles:
        assert set(shown.loc[~shown["kept"], "reason"]) == set(table.loc[~table["kept"], "reason"])
        assert shown["kept"].any() == table["kept"].any()
        no_detection = lambda t: (~t.groupby("time_ns")["kept"].any()).any()  # noqa: E731
        assert no_detection(shown) == no_detection(table)
    for time_ns, kind in tiles.itertuples(index=False):  # each frame shows the decision it stands for
        rows = table[table["time_ns"] == time_ns]
        if kind == KEPT:
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
    tile = draw_tile(image, rows, rows.iloc[0], "0.00 s kept")
    assert tile.shape == (TITLE_PX + TILE_PX, TILE_PX, 3)
    body = tile[TITLE_PX:]
    x0, y0, side = crop_square(123.4, 77.8, 20.0, 480, 360)
    assert side == 61  # the larger of 12 diameters of a 20 px blob (60.55 px) and width / 8 (60), rounded
    kept_at = tile_position((123.4, 77.8), x0, y0, side)
    radius = int(round(2 * np.sqrt(20 / np.pi) / 2 * TILE_PX / side)) + 4
    assert _near(body, KEPT_BGR, kept_at, radius + 2) and not _near(body, KEPT_BGR, kept_at, radius - 4)
    assert _near(body, REFUSED_BGR, tile_position((140.0, 90.0), x0, y0, side), radius + 2)
    refused_only = draw_tile(image, rows.iloc[1:], rows.iloc[1], "0.00 s slow")
    assert not _near(refused_only, KEPT_BGR, (TILE_PX / 2, TILE_PX / 2 + TITLE_PX), TILE_PX)


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
    sheet = ball_qa_sheet(frames(), times, table, "s00 cam0")
    chosen = choose_tiles(table, 24)
    assert sorted(CountingFrame.decoded) == sorted(chosen["time_ns"])
    assert passed[-1] == chosen["time_ns"].max()  # the stream is left after the last chosen frame
    band = sheet.shape[0] - 4 * (TITLE_PX + TILE_PX)  # 4 rows of tiles under the summary band
    assert sheet.shape[1] == TILE_COLUMNS * TILE_PX and 30 <= band < 90


def test_the_stage_writes_the_sheet_of_a_tiny_stream(tmp_path):
    """20 frames of an orange ball crossing a grey room beside a static box: the sheet has a tile per
    frame with candidates (20 < 24), 4 rows of 6, and its kept tiles show the ball circled green."""
    stream, candidates = tmp_path / "cam0.mcap", tmp_path / "cam0.parquet"
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
    out = tmp_path / "ball_qa_s00_cam0.jpg"
    params = {"session": "s00", "cam": "cam0", "strict": True,
              "reading": {"timestamps": None, "start_ns": 0, "topic": None}}
    report_ball_qa.main(StageContext("report_ball_qa", Named(stream=str(stream), timestamps=[],
                                                             candidates=str(candidates)),
                                     Named(figure=str(out)), params, None))
    sheet = cv2.imread(str(out))
    band = sheet.shape[0] - 4 * (TITLE_PX + TILE_PX)
    assert sheet.shape[1] == TILE_COLUMNS * TILE_PX and 30 <= band < 90
    tiles = choose_tiles(pd.DataFrame(rows), 24)
    assert len(tiles) == 20
    first = sheet[band + TITLE_PX:band + TITLE_PX + TILE_PX, :TILE_PX]  # the first kept frame's tile
    frame = (tiles["time_ns"].iloc[0] - FIRST_NS) // FRAME_NS
    u, v = 60.0 + 15 * frame, 120.0 + 4 * frame
    x0, y0, side = crop_square(u, v, 20.0, 480, 360)
    assert _near(first, KEPT_BGR, tile_position((u, v), x0, y0, side), 20)


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
