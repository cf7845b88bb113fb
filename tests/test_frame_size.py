"""Each camera stream's frame size, read from its images in any format, and checked by the pose2d rule
against the camera's calibration (a video 8 px narrower than its calibration is refused, naming both
sizes); the rule's OpenPose files counted against the video's frames."""

import shutil

import av
import cv2
import numpy as np
import pandas as pd
import pytest
from test_camera_streams import TIMES, H, W, jpeg, raw_bag, square_image

from pingpong.common.script import Named, StageContext
from pingpong.io.camera_streams import CameraStreamError, camera_frame_size
from pingpong.io.mcap_io import CameraStreamWriter, read_camera_stream
from pingpong.stages import pose2d as stage

N_FRAMES = 30
READING = {"timestamps": None, "start_ns": 0, "topic": None}


def write_video(frames, path, width: int) -> None:
    """BGR frames as a lossless video (FFV1 in Matroska), each cut to its first `width` columns."""
    with av.open(str(path), "w") as container:
        stream = container.add_stream("ffv1", rate=100)
        stream.height, stream.width = frames[0].shape[0], width
        for image in frames:
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image[:, :width]), format="bgr24")
            container.mux(stream.encode(frame))
        container.mux(stream.encode())


def tiny_frames(tiny_run) -> list[np.ndarray]:
    """The first N_FRAMES images of the tiny run's cam0."""
    frames = []
    for _, data in read_camera_stream(tiny_run / "raw/sessions/s00/cam0.mcap"):
        frames.append(cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR))
        if len(frames) == N_FRAMES:
            return frames
    raise AssertionError("the tiny run's cam0 has fewer frames than the test needs")


def test_the_size_of_every_format(tmp_path):
    images = [square_image(i) for i in range(3)]
    with CameraStreamWriter(tmp_path / "cam.mcap", 0, "cam0") as writer:
        for t, image in zip(TIMES, images, strict=False):
            writer.add(t, jpeg(image))
    write_video(images, tmp_path / "cam.mkv", W - 8)
    assert camera_frame_size(tmp_path / "cam.mcap") == (W, H)
    assert camera_frame_size(raw_bag(tmp_path / "raw.mcap", "mono8")) == (W, H)  # rows with padding
    assert camera_frame_size(tmp_path / "cam.mkv") == (W - 8, H)


def test_the_first_frame_that_decodes_gives_the_size(tmp_path):
    with CameraStreamWriter(tmp_path / "cam.mcap", 0, "cam0") as writer:
        writer.add(TIMES[0], b"\xff\xd8 not a jpeg")
        writer.add(TIMES[1], jpeg(square_image(1)))
    assert camera_frame_size(tmp_path / "cam.mcap") == (W, H)
    with CameraStreamWriter(tmp_path / "broken.mcap", 0, "cam0") as writer:
        writer.add(TIMES[0], b"\xff\xd8 not a jpeg")
    with pytest.raises(CameraStreamError, match=r"broken.mcap: no frame decodes \(frame 0: .*\); expected "):
        camera_frame_size(tmp_path / "broken.mcap")


def run_pose2d(tiny_run, tmp_path, video, n_files: int = N_FRAMES) -> pd.DataFrame:
    """The pose2d rule's entry on a video and the first n_files of the tiny run's cam0 OpenPose files."""
    openpose = tmp_path / "openpose"
    openpose.mkdir(exist_ok=True)
    for frame in range(n_files):
        name = f"s00_cam0_{frame:012d}_keypoints.json"
        shutil.copy(tiny_run / "raw/sessions/s00/openpose/cam0" / name, openpose / name)
    inputs = Named(cameras=str(tiny_run / "interim/calibration/cameras.json"), stream=str(video),
                   timestamps=[], openpose=str(openpose))
    params = {"cam": "cam0", "min_confidence": 0.3, "model": "BODY_25", "pattern": "openpose",
              "reading": READING, "strict": False, "code": ""}
    out = tmp_path / "cam0.parquet"
    stage.main(StageContext("pose2d", inputs, Named(pose2d=str(out)), params, None))
    return pd.read_parquet(out)


def test_a_video_narrower_than_its_calibration_is_refused(tiny_run, tmp_path):
    frames = tiny_frames(tiny_run)
    height, width = frames[0].shape[:2]
    write_video(frames, tmp_path / "narrow.mkv", width - 8)
    cameras = tiny_run / "interim/calibration/cameras.json"
    told = (rf"narrow.mkv: frames of {width - 8} x {height} px, but camera cam0 is calibrated for {width} x "
            rf"{height} px in {cameras}; expected the stream at the calibration's size")
    with pytest.raises(CameraStreamError, match=told):
        run_pose2d(tiny_run, tmp_path, tmp_path / "narrow.mkv")
    write_video(frames, tmp_path / "full.mkv", width)
    table = run_pose2d(tiny_run, tmp_path, tmp_path / "full.mkv")
    assert table["time_ns"].nunique() == N_FRAMES


def test_one_openpose_file_more_than_video_frames_is_named_and_left_out(tiny_run, tmp_path):
    frames = tiny_frames(tiny_run)
    write_video(frames, tmp_path / "full.mkv", frames[0].shape[1])
    told = (rf"{tmp_path / 'openpose'}: 1 keypoints files past the video's last frame 29 left out: "
            r"s00_cam0_000000000030_keypoints.json$")
    with pytest.warns(UserWarning, match=told):
        table = run_pose2d(tiny_run, tmp_path, tmp_path / "full.mkv", n_files=N_FRAMES + 1)
    assert table["time_ns"].nunique() == N_FRAMES
