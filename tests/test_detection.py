"""Ball detection against the twin's pixel truth, on synthetic discs, and on a stream with a corrupt frame.

"Visible" means visibility >= 0.5: at least half of the ball's blurred image is in the frame and not
hidden, so its thresholded blob keeps >= 4 px at 480x360. A thinner sliver (behind a player's arm, at
the image edge) is 1-3 px, the size of the colour-blend specks the detector's minimum area rejects, so
missing it is not counted against recall; detecting it within 5 px is not counted as false either.
"""

import logging

import cv2
import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

import pingpong.perception.detection as detection
from pingpong.common.artifacts import Provenance, read_table, write_table
from pingpong.common.seeding import rng_for
from pingpong.perception.detection import BallDetector, detect_ball, detect_stream
from pingpong.perception.schemas import DETECTIONS
from pingpong.twin import render
from pingpong.twin.cameras import record_camera
from pingpong.twin.rig import make_rig
from pingpong.twin.session import FaultRates, simulate_session

VISIBLE = 0.5  # visibility from which a ball counts as visible (module docstring)
FALSE_PX = 5.0  # a detection further than this from the truth is a false detection
WIDTH, HEIGHT = 480, 360
WALL_BGR = render.hsv_to_bgr(*render.WALL_HSV)


@pytest.fixture(scope="module")
def twin_stream():
    """One camera's JPEG frames of a 2-rally twin session (~900 frames, 480x360, q90) and its ball truth."""
    seed = 5
    truth = simulate_session(2, FaultRates(), rng_for(seed, "session"))
    camera = make_rig(rng_for(seed, "rig"), 4, WIDTH, HEIGHT)[0]
    rng = rng_for(seed, "camera")
    lab = render.make_lab(rng_for(seed, "lab"))
    # one background, with the sometimes-present ball bucket: a session this short stays in the first
    # of the twin's 20 s distractor periods anyway, and rendering the lab twice would double the setup
    background = render.render_background(camera, lab, rng, intermittent=True)
    looks = render.make_player_looks(rng, 3)
    frames, rows = [], []
    for t, jpeg, row in record_camera(camera, (background, background), looks, truth.ball, truth.people,
                                      truth.paddles, rng, 90):
        frames.append((t, jpeg))
        rows.append(row)
    return frames, pd.DataFrame(rows)


@pytest.fixture(scope="module")
def scored(twin_stream):
    """Detections of the twin stream, their distance to the truth (px) and the truth's visibility."""
    frames, truth = twin_stream
    found = detect_stream(frames, BallDetector())
    error = np.hypot(found["u"] - truth["u"], found["v"] - truth["v"]).to_numpy()
    return found, error, truth["visibility"].to_numpy()


def test_visible_balls_are_found_within_a_pixel(scored):
    found, error, visibility = scored
    visible = visibility >= VISIBLE
    hit = found["detected"].to_numpy() & (error <= FALSE_PX)
    assert visible.sum() > 300
    assert hit[visible].mean() >= 0.99
    assert np.median(error[visible & hit]) < 1.0  # measured 0.12 px
    assert np.percentile(error[visible & hit], 95) < 1.0


def test_false_detections_are_rare(scored):
    found, error, visibility = scored
    detected = found["detected"].to_numpy()
    false = detected & ((visibility == 0) | ~(error <= FALSE_PX))  # NaN error: the truth has no ball
    assert (visibility == 0).sum() > 300  # plenty of frames between and after the rallies
    assert false.mean() < 0.005


def test_detections_table_is_an_artifact(scored, tmp_path):
    found, _, _ = scored
    assert found.dtypes["time_ns"] == np.int64 and found.dtypes["detected"] == np.bool_
    assert found.loc[~found["detected"], ["u", "v"]].isna().all().all()
    assert (found.loc[found["detected"], "area_px"] >= 3).all()
    write_table(found, tmp_path / "cam0.parquet", DETECTIONS, Provenance.of("detection"))
    pd.testing.assert_frame_equal(read_table(tmp_path / "cam0.parquet", DETECTIONS), found)


def test_a_corrupt_frame_is_marked_logged_skipped_and_tracking_restarts(twin_stream, scored, caplog,
                                                                        monkeypatch):
    frames, _ = twin_stream
    found, _, _ = scored
    tracked = np.flatnonzero(found["detected"].to_numpy()[:-12] & found["detected"].to_numpy()[12:])
    start = int(tracked[0])  # 12 frames in a row with the ball
    clip = frames[start:start + 12]
    bad = 5
    clip[bad] = (clip[bad][0], clip[bad][1][: len(clip[bad][1]) // 2])  # a truncated JPEG
    searched_around = []
    real_detect = detection.detect_ball

    def spy(image, detector, previous_uv=None):
        searched_around.append(previous_uv)
        return real_detect(image, detector, previous_uv)

    monkeypatch.setattr(detection, "detect_ball", spy)
    with caplog.at_level(logging.WARNING, logger=detection.__name__):
        out = detect_stream(clip, BallDetector())
    assert out["decode_ok"].tolist() == [i != bad for i in range(12)]
    assert not out["detected"][bad] and np.isnan(out["u"][bad])
    assert str(clip[bad][0]) in caplog.text
    # the corrupt frame is not searched; the next one searches the whole frame, then the window resumes
    assert len(searched_around) == 11
    assert searched_around[bad] is None
    assert all(uv is not None for uv in searched_around[bad + 1:])
    assert out["detected"].sum() == 11
    np.testing.assert_allclose(out.drop(index=bad)[["u", "v"]].to_numpy(),
                               found.iloc[start:start + 12].drop(index=start + bad)[["u", "v"]].to_numpy())


def test_an_empty_frame_counts_as_corrupt(caplog):
    with caplog.at_level(logging.WARNING, logger=detection.__name__):
        out = detect_stream([(7, b""), (8, b"\xff\xd8 not a jpeg")], BallDetector())
    assert not out["decode_ok"].any() and not out["detected"].any()
    assert "7 ns" in caplog.text and "8 ns" in caplog.text


# ------------------------------------------------------------------------------- synthetic images

def draw_disc(image: np.ndarray, u: float, v: float, radius: float, bgr, ss: int = 16) -> None:
    """Blend an anti-aliased disc (exact coverage of ss x ss subsamples per pixel) into a BGR float image."""
    x0, y0 = int(np.floor(u - radius - 1)), int(np.floor(v - radius - 1))
    x1, y1 = int(np.ceil(u + radius + 2)), int(np.ceil(v + radius + 2))
    offsets = (np.arange(ss) + 0.5) / ss - 0.5  # pixel centres at integer coordinates (OpenCV)
    xs = (np.arange(x0, x1)[:, None] + offsets).ravel()
    ys = (np.arange(y0, y1)[:, None] + offsets).ravel()
    inside = (xs[None, :] - u) ** 2 + (ys[:, None] - v) ** 2 <= radius**2
    alpha = inside.reshape(y1 - y0, ss, x1 - x0, ss).mean(axis=(1, 3))[..., None]
    image[y0:y1, x0:x1] = image[y0:y1, x0:x1] * (1 - alpha) + np.asarray(bgr, np.float32) * alpha


def canvas(bgr=WALL_BGR) -> np.ndarray:
    return np.tile(np.asarray(bgr, np.float32), (HEIGHT, WIDTH, 1))


def to_uint8(image: np.ndarray) -> np.ndarray:
    return np.clip(image + 0.5, 0, 255).astype(np.uint8)


@given(u=st.floats(40, 440), v=st.floats(40, 320), radius=st.floats(2.0, 4.5),
       background=st.sampled_from([render.FLOOR_HSV, render.CEILING_HSV]))
def test_an_orange_disc_on_grey_is_found_within_a_tenth_of_a_pixel(u, v, radius, background):
    image = canvas(render.hsv_to_bgr(*background))
    draw_disc(image, u, v, radius, render.BALL_BGR)
    found = detect_ball(to_uint8(image), BallDetector())
    assert found is not None
    assert np.hypot(found[0] - u, found[1] - v) < 0.1
    assert found[2] >= 3


@given(u=st.floats(40, 440), v=st.floats(40, 320), radius=st.floats(1.5, 4.5),
       background=st.sampled_from([render.WALL_HSV, render.TABLE_TOP_HSV]))
def test_an_orange_disc_on_a_saturated_colour_is_found_within_a_third_of_a_pixel(u, v, radius, background):
    # a blend of orange with a saturated blue-green passes through grey, so edge pixels' saturation
    # understates their coverage (detection.py's docstring): measured up to 0.25 px for 1.5 px discs
    image = canvas(render.hsv_to_bgr(*background))
    draw_disc(image, u, v, radius, render.BALL_BGR)
    found = detect_ball(to_uint8(image), BallDetector())
    assert found is not None
    assert np.hypot(found[0] - u, found[1] - v) < 0.3


DISTRACTORS = {"poster": render.POSTER_HSV, "cardboard": render.CARDBOARD_HSV,
               "extinguisher": render.EXTINGUISHER_HSV, "bucket": render.BUCKET_HSV,
               **{f"skin{i}": hsv for i, hsv in enumerate(render.SKIN_HSVS)},
               "handle": (15, 100, 160), "red rubber": (0, 210, 165)}  # render.HANDLE, RED_RUBBER


@pytest.mark.parametrize("hsv", DISTRACTORS.values(), ids=DISTRACTORS.keys())
def test_distractor_colours_are_rejected_with_noise_and_jpeg(hsv):
    rng = np.random.default_rng(3)
    image = canvas()
    draw_disc(image, 200.3, 150.6, 25.0, render.hsv_to_bgr(*hsv))
    noisy = to_uint8(image + rng.normal(0, 2.0, image.shape))  # the twin's sensor noise
    decoded = cv2.imdecode(np.frombuffer(render.encode_jpeg(noisy, 90), np.uint8), cv2.IMREAD_COLOR)
    assert detect_ball(decoded, BallDetector()) is None
    draw_disc(image, 350.2, 90.7, 2.5, render.BALL_BGR)  # a small ball beside the large distractor
    found = detect_ball(to_uint8(image), BallDetector())
    assert found is not None and np.hypot(found[0] - 350.2, found[1] - 90.7) < 0.1


def _jpeg(image: np.ndarray) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(render.encode_jpeg(to_uint8(image), 90), np.uint8), cv2.IMREAD_COLOR)


@pytest.mark.parametrize("blur", [0.5, 0.8, 1.0])
def test_a_red_yellow_seam_is_not_a_ball_but_a_ball_on_either_colour_is(blur):
    # red rubber held in front of the yellow bucket: their anti-aliased edge is true orange, a blob that
    # passes every colour test (without the seam rule the detector returns it at these blurs)
    image = canvas()
    draw_disc(image, 200.3, 150.2, 40.0, render.hsv_to_bgr(*render.BUCKET_HSV))
    draw_disc(image, 255.7, 150.6, 30.0, render.hsv_to_bgr(*DISTRACTORS["red rubber"]))
    image = cv2.GaussianBlur(image, (0, 0), blur)
    assert detect_ball(_jpeg(image), BallDetector()) is None
    for u, v in ((262.4, 140.3), (185.2, 160.7)):  # a ball in front of the red, then of the yellow
        with_ball = image.copy()
        draw_disc(with_ball, u, v, 3.0, render.BALL_BGR)
        found = detect_ball(_jpeg(with_ball), BallDetector())
        assert found is not None and np.hypot(found[0] - u, found[1] - v) < 0.5


def test_the_window_searches_only_around_the_previous_detection():
    image = canvas()
    draw_disc(image, 100.4, 100.2, 2.5, render.BALL_BGR)
    draw_disc(image, 400.6, 250.3, 4.0, render.BALL_BGR)  # larger, far outside the window
    image = to_uint8(image)
    detector = BallDetector()
    assert detector.scaled(WIDTH)[2] == 33  # 200 px at 1440 wide: a 67 px square at 480
    near = detect_ball(image, detector, previous_uv=(110.0, 95.0))
    assert np.hypot(near[0] - 100.4, near[1] - 100.2) < 0.1
    whole = detect_ball(image, detector)
    assert np.hypot(whole[0] - 400.6, whole[1] - 250.3) < 0.1
    assert detect_ball(image, detector, previous_uv=(250.0, 180.0)) is None  # lost: the caller resets


def test_sizes_scale_with_the_image_width():
    detector = BallDetector()
    assert detector.scaled(1440) == (36.0, 900.0, 100)
    assert detector.scaled(480) == pytest.approx((4.0, 100.0, 33))
    image = canvas()
    draw_disc(image, 240.0, 180.0, 0.8, render.BALL_BGR)  # 2 px: a colour-blend speck, not a ball
    assert detect_ball(to_uint8(image), detector) is None
    big = np.tile(np.asarray(render.BALL_BGR, np.float32), (HEIGHT, WIDTH, 1))
    big[:, :100] = WALL_BGR
    assert detect_ball(to_uint8(big), detector) is None  # an orange wall is no ball
