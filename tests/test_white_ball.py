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

import numpy as np
import pytest

from pingpong.io.camera_streams import CameraFrame
from pingpong.perception.ball_colour import main as ball_colour
from pingpong.perception.detection import Scene, ball_detector, detect_stream, scene_image

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
