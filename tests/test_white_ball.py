"""The white-ball setting (config perception.ball.colour: white) on real frames of play.

The frames: 58 labelled 1920x1080 frames of an amateur indoor game with a white ball in a cluttered room
(../shared/realdata/white_ball_frames, its README.md), from the Roboflow project tenis-ball-laoaj (workspace
task1-bxvrc, version 1) in the public repository Rahimdzx/table-tennis-ball-detection (commit c16289e),
licence CC BY 4.0: attribution to that project and repository is required wherever results on them are shown.

Each frame is searched alone (the frames are sparse samples: no tracking) as the detection stage searches a
stream's first frame: detection.ball_detector of the config's `colour: white`, then detect_stream with the
scene image (detection.scene_image: here the median of all 58 frames, which spread over the video as the
stage's 25 samples spread over a stream). A frame counts as a hit when the detected centre lies in its
labelled box. The white setting (detection.BALL_COLOURS) was chosen on the even-numbered frames (file names
sorted) and held out on the odd ones (the module docstring of pingpong.perception.detection, "A white ball").
"""

from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from pingpong.io.camera_streams import CameraFrame
from pingpong.perception.ball_colour import main as ball_colour
from pingpong.perception.detection import (
    Scene,
    _differs_from_scene,
    ball_detector,
    detect_ball,
    detect_stream,
    scene_image,
)

# the project's shared folder beside the checkout, or where these machines mount it (a clean clone for CI
# may lie elsewhere)
FRAMES = next((p for p in (Path(__file__).resolve().parents[2] / "shared", Path("/work/shared"))
               if p.is_dir()), Path("/work/shared")) / "realdata" / "white_ball_frames"
WHITE = ball_detector({"colour": "white"})


@pytest.fixture(scope="module")
def frames():
    """(CameraFrame, labelled box (cx, cy, w, h) px) of each frame, by file name."""
    if not (FRAMES / "images").is_dir():
        pytest.skip(f"the real white-ball frames are not at {FRAMES} (the project's shared folder)")
    out = []
    for k, image in enumerate(sorted((FRAMES / "images").glob("*.jpg"))):
        _, cx, cy, w, h = map(float, (FRAMES / "labels" / f"{image.stem}.txt").read_text().split())
        out.append((CameraFrame(k, image.read_bytes()), (cx * 1920, cy * 1080, w * 1920, h * 1080)))
    return out


@pytest.fixture(scope="module")
def hits(frames):
    """Whether the white setting's ball lies in each frame's labelled box."""
    scene = Scene(scene_image((frame for frame, _ in frames), count=len(frames)))
    out = []
    for frame, (cx, cy, w, h) in frames:
        found = detect_stream([frame], WHITE, scene=scene).iloc[0]
        inside = abs(found["u"] - cx) <= w / 2 and abs(found["v"] - cy) <= h / 2
        out.append(bool(found["detected"]) and inside)
    return np.array(out)


def test_the_white_ball_is_found_in_its_box(hits):
    # measured: 28 of the 29 fitted frames, 26 of the 29 held out (54 of 58, 93 %); the misses are balls in
    # a hand (one in its shadow, below the value floor), a ball over a red bat and one over a pale floor
    assert len(hits) == 58
    assert hits[0::2].sum() >= 28 and hits[1::2].sum() >= 26


def test_the_white_ball_meets_the_bar(hits):
    # issue 49's bar: the ball's box hit in >= 90 % of the frames
    assert hits.mean() >= 0.9


def test_the_colour_command_measures_a_pale_ball(frames, capsys):
    images = sorted((FRAMES / "images").glob("*.jpg"))[:4]
    labels = [str(FRAMES / "labels" / f"{p.stem}.txt") for p in images]
    ball_colour([str(p) for p in images] + ["--labels"] + labels)
    printed = capsys.readouterr().out
    assert "perception:\n  ball:\n    hsv: {hue: [" in printed
    value = [int(v) for v in printed.split("value: [")[1].split("]")[0].split(",")]
    assert value[1] >= 240  # the ball's core is near white


BGR = st.tuples(*[st.integers(0, 255)] * 3)


def _hsv(bgr) -> np.ndarray:
    return cv2.cvtColor(np.array([[bgr]], np.uint8), cv2.COLOR_BGR2HSV)


@settings(max_examples=200, deadline=None)
@given(scene=st.tuples(*[st.integers(40, 255)] * 3), gain=st.floats(0.4, 1.0))
def test_a_shadow_on_the_scene_is_no_change(scene, gain):
    # a shadow scales the scene's colour: not brighter, and on the scene's colour line up to rounding and
    # the HSV round trip (a few levels, far below the white setting's 30)
    shaded = tuple(int(round(gain * c)) for c in scene)
    differs = _differs_from_scene(_hsv(shaded), np.array([[scene]], np.uint8), WHITE.scene_contrast_min)
    assert not differs[0, 0]


@settings(max_examples=300, deadline=None)
@given(pixel=BGR, scene=BGR, contrast=st.integers(5, 80))
def test_the_colour_test_is_brighter_or_off_the_scene_colour(pixel, scene, contrast):
    # against the definition in float64: brighter in HSV value, or the distance of the pixel (as the test
    # sees it, back from HSV) from its projection on the scene's colour
    hsv = _hsv(pixel)
    seen = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0].astype(float)
    e = np.asarray(scene, float)
    off = np.linalg.norm(seen - (seen @ e) / max(e @ e, 1.0) * e)
    assume(abs(off - contrast) > 0.01 * contrast)  # float32 against float64 at the threshold
    expected = int(hsv[0, 0, 2]) - max(scene) >= contrast or off >= contrast
    assert _differs_from_scene(hsv, np.array([[scene]], np.uint8), contrast)[0, 0] == expected


def test_a_white_ball_over_a_pale_floor_of_its_brightness_differs():
    # frame 4's ball and floor (median BGR in its box): the ball is no brighter, its colour is off by ~50
    floor, ball = (217, 188, 173), (194, 206, 218)
    assert _differs_from_scene(_hsv(ball), np.array([[floor]], np.uint8), WHITE.scene_contrast_min)[0, 0]


def test_the_ball_ringed_by_the_still_scene_is_taken():
    # a grey room; a player (a blue patch the scene does not hold) with a larger white disc on his shirt,
    # and a smaller white ball in free air: the ball, though the other blob is larger and as round
    scene = np.full((540, 960, 3), 120, np.uint8)
    image = scene.copy()
    cv2.rectangle(image, (600, 150), (800, 450), (140, 60, 40), -1)
    cv2.circle(image, (700, 300), 9, (235, 240, 245), -1)
    cv2.circle(image, (300, 200), 6, (235, 240, 245), -1)
    u, v, _ = detect_ball(image, WHITE, scene=Scene(scene))
    assert np.hypot(u - 300, v - 200) < 1



def test_a_white_ball_is_tracked_through_a_stream():
    # the stage's path past the first frame (each searched in the window around the last ball on its 1/2
    # decode, its centre on the window upsampled): a pale floor with a darker band, a ball flying across
    # both at 1920x1080; measured: within 0.07-0.13 px of the drawn centre
    scene = np.full((1080, 1920, 3), (205, 190, 180), np.uint8)
    scene[500:700] = (90, 110, 80)
    truth = [(400.0 + 60 * k, 450.0 + 25 * k) for k in range(8)]
    frames = []
    for k, (u, v) in enumerate(truth):
        image = scene.copy()
        cv2.circle(image, (round(u * 16), round(v * 16)), 10 * 16, (215, 225, 235), -1, cv2.LINE_AA, shift=4)
        jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])[1]
        frames.append(CameraFrame(k, jpeg.tobytes()))
    found = detect_stream(frames, WHITE, scene=Scene(scene))
    assert found["detected"].all()
    assert np.hypot(found["u"] - [u for u, _ in truth], found["v"] - [v for _, v in truth]).max() < 1.0
