"""Rule detection: the ball's pixel centre in every frame of one camera's stream (any format
pingpong.io.camera_streams reads; frames that do not decode cleanly are marked)."""

import logging

from tqdm import tqdm

from pingpong.common.artifacts import write_table
from pingpong.io.camera_streams import open_camera_stream
from pingpong.perception.detection import BallDetector, detect_stream
from pingpong.perception.schemas import DETECTIONS


def main(ctx):
    _, frames = open_camera_stream(ctx.input.stream, ctx.params["strict"], **ctx.params["reading"])
    frames = tqdm(frames, mininterval=10, unit="frame")
    table = detect_stream(frames, BallDetector())
    write_table(table, ctx.output.detections, DETECTIONS, ctx.provenance())
    logging.info("%s: ball found in %d of %d frames, %d frames did not decode", ctx.input.stream,
                 table["detected"].sum(), len(table), (~table["decode_ok"]).sum())
