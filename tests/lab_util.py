"""Recordings laid out as a lab brings them, made from the tiny twin run's (the lab-session tests)."""

import itertools
import shutil

import av
import cv2
import numpy as np

from pingpong.io.mcap_io import read_camera_stream

# H.264 (near-lossless, no chroma subsampling) where this PyAV build has libx264, else FFV1 (lossless,
# always in FFmpeg): either way the ball keeps its colour
CODEC, OPTIONS = (("libx264", {"crf": "12", "preset": "ultrafast"}) if "libx264" in av.codecs_available
                  else ("ffv1", {}))


def write_video(mcap, path, narrower_px=0) -> np.ndarray:
    """The camera's JPEG frames as a video at 100 fps (CODEC), their right narrower_px columns cut off;
    returns the frame times."""
    times = []
    with av.open(str(path), "w") as container:
        stream = container.add_stream(CODEC, rate=100, options=OPTIONS)
        for time_ns, jpeg in read_camera_stream(mcap):
            image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
            image = np.ascontiguousarray(image[:, :image.shape[1] - narrower_px])
            if not times:
                stream.height, stream.width = image.shape[:2]
                stream.pix_fmt = "yuv444p"  # no chroma subsampling: the ball's orange stays orange
            container.mux(stream.encode(av.VideoFrame.from_ndarray(image, format="bgr24")))
            times.append(time_ns)
        container.mux(stream.encode())
    return np.asarray(times, np.int64)


def remux(source, dest, crop_right_px: int = 0) -> None:
    """The video `source`'s packets copied, not decoded, into the container that `dest`'s suffix names: the
    same frames (all 8,442 of a tiny-run camera's .mp4 remuxed to .mkv decode equal to that camera encoded
    straight to .mkv, with the same time base and duration) in 0.15 s, where write_video takes ~22 s.
    crop_right_px: that many columns cut off every frame's right by the H.264 stream's own cropping (FFmpeg's
    h264_metadata filter rewrites its parameter sets): the 8,442 frames decode equal to the source's left
    472 of 480 columns, the header says 472 px, in 0.5 s where write_video's narrower_px takes ~30 s."""
    with av.open(str(source)) as container, av.open(str(dest), "w") as out:
        video = container.streams.video[0]
        stream = out.add_stream_from_template(video)
        # not the demuxer's empty end-of-stream packet
        packets = (packet for packet in container.demux(video) if packet.dts is not None)
        if crop_right_px:
            cropping = f"h264_metadata=crop_right={crop_right_px}"
            crop = av.bitstream.BitStreamFilterContext(cropping, video, stream)
            # None at the end: what the filter still holds
            packets = itertools.chain.from_iterable(crop.filter(p) for p in itertools.chain(packets, [None]))
        for packet in packets:
            packet.stream = stream
            out.mux(packet)


def dotted_openpose(source, dest, cam) -> None:
    """OpenPose's NAME_000000000012_keypoints.json files renamed to the layout cam0.00012.json."""
    dest.mkdir(parents=True)
    for f in source.glob("*_keypoints.json"):
        frame = int(f.name.rsplit("_", 2)[1])
        shutil.copy(f, dest / f"{cam}.{frame:05d}.json")
