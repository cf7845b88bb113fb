"""Rule detection: the ball's pixel centre in every frame of one camera's stream (any format
pingpong.io.camera_streams reads; frames that do not decode cleanly are marked), and every ball candidate
the detector weighed (BALL_CANDIDATES). The ball is config perception.ball (detection.ball_detector), found
by its `method`: colour (detection.detect_stream; its candidates are its detections, each kept) or track
(ball_track.detect_stream: moving ball-coloured candidates linked into ballistic tracks). A colour detector
that compares with the scene (the white ball's) and the track method, which starts its running background
from it, first read the stream's scene image (detection.scene_image: the median of sampled frames)."""

import logging

from tqdm import tqdm

from pingpong.common.artifacts import write_table
from pingpong.io.camera_streams import open_camera_stream
from pingpong.perception import ball_track, detection
from pingpong.perception.schemas import BALL_CANDIDATES, DETECTIONS


def _frames(ctx):
    _, frames = open_camera_stream(ctx.input.stream, ctx.params["strict"], **ctx.params["reading"])
    return frames


def _scene_image(ctx):
    """The stream's scene image (BGR), or None where none of its sampled frames decodes."""
    image = ball_track.scene_for(_frames(ctx))
    logging.info("%s: the scene image from every %dth frame, up to %d", ctx.input.stream,
                 detection.SCENE_EVERY, detection.SCENE_FRAMES)
    return image


def main(ctx):
    ball = ctx.params["ball"]
    detector = detection.ball_detector(ball)
    track = ball.get("method", "colour") == "track"
    scene = _scene_image(ctx) if track or detector.scene_contrast_min > 0 else None
    frames = tqdm(_frames(ctx), mininterval=10, unit="frame")
    if track:
        settings = ball_track.track_settings(ball["track"])
        table, candidates = ball_track.detect_stream(frames, detector, settings, scene)
    else:
        scene = None if scene is None else detection.Scene(scene)
        table = detection.detect_stream(frames, detector, scene=scene)
        candidates = ball_track.colour_candidates(table)
    write_table(table, ctx.output.detections, DETECTIONS, ctx.provenance())
    write_table(candidates, ctx.output.candidates, BALL_CANDIDATES, ctx.provenance())
    logging.info("%s: ball found in %d of %d frames (method %s, %d candidates), %d frames did not decode",
                 ctx.input.stream, table["detected"].sum(), len(table), ball.get("method", "colour"),
                 len(candidates), (~table["decode_ok"]).sum())
