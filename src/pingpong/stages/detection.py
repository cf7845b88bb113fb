"""Rule detection: the ball's pixel centre in every frame of one camera's stream (any format
pingpong.io.camera_streams reads; frames that do not decode cleanly are marked). The ball is config
perception.ball (detection.ball_detector); a detector that compares with the scene (the white ball's) first
reads the stream's scene image (detection.scene_image: the median of sampled frames)."""

import logging

from tqdm import tqdm

from pingpong.common.artifacts import write_table
from pingpong.io.camera_streams import open_camera_stream
from pingpong.perception import detection
from pingpong.perception.schemas import DETECTIONS


def _scene(ctx) -> detection.Scene | None:
    """The stream's scene image, or None where none of its sampled frames decodes."""
    _, frames = open_camera_stream(ctx.input.stream, ctx.params["strict"], **ctx.params["reading"])
    image = detection.scene_image(frames, detection.SCENE_EVERY, detection.SCENE_FRAMES)
    logging.info("%s: the scene image from every %dth frame, up to %d", ctx.input.stream,
                 detection.SCENE_EVERY,
                 detection.SCENE_FRAMES)
    return None if image is None else detection.Scene(image)


def main(ctx):
    detector = detection.ball_detector(ctx.params["ball"])
    scene = _scene(ctx) if detector.scene_contrast_min > 0 else None
    _, frames = open_camera_stream(ctx.input.stream, ctx.params["strict"], **ctx.params["reading"])
    frames = tqdm(frames, mininterval=10, unit="frame")
    table = detection.detect_stream(frames, detector, scene=scene)
    write_table(table, ctx.output.detections, DETECTIONS, ctx.provenance())
    logging.info("%s: ball found in %d of %d frames, %d frames did not decode", ctx.input.stream,
                 table["detected"].sum(), len(table), (~table["decode_ok"]).sum())
