"""Rule report_ball_qa: one camera's ball-detector decisions (kept, refused and why) and its multi-view
ball (interim/ball_views/{session}/{cam}.parquet: where it is filled, dropped or moved) as a contact sheet
(pingpong.reports.ball_qa), reports/figures/ball_qa_{session}_{cam}.jpg."""

from pathlib import Path

import cv2

from pingpong.common.artifacts import read_table
from pingpong.common.atomic import write_bytes_atomic
from pingpong.io.camera_streams import camera_frame_times, open_camera_stream
from pingpong.perception.schemas import BALL_CANDIDATES, DETECTIONS
from pingpong.reports.ball_qa import ball_qa_sheet

JPEG_QUALITY = 90  # the sheet's JPEG: the tiles' pixels as the detector saw them, ~0.3 MB a camera


def main(ctx):
    p, i = ctx.params, ctx.input
    times = camera_frame_times(i.stream, p["strict"], **p["reading"])
    candidates = read_table(i.candidates, BALL_CANDIDATES)
    views = read_table(Path(i.ball_views) / f"{p['cam']}.parquet", DETECTIONS)  # the session's folder
    _, frames = open_camera_stream(i.stream, p["strict"], **p["reading"])
    try:
        sheet = ball_qa_sheet(frames, times, candidates, views, f"{p['session']} {p['cam']}")
    finally:
        frames.close()  # a video's container closes now, not when collected
    jpeg = cv2.imencode(".jpg", sheet, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])[1].tobytes()
    write_bytes_atomic(ctx.output.figure, jpeg)
