"""JPEG fuzzed (issue 37): whole frames (`decode_jpeg`) and row bands (`decode_jpeg_rows`).

Each damaged frame goes through the decoder in a forked child (tests/fuzz_util.py). The decoders return
(image or None, reason) and never raise on data: a non-empty reason marks the frame bad, and the summary
here warns with the file's name as the detection stage logs a bad frame with its own. Allowed: a frame
marked bad, or the undamaged pixels. Silent: only changed pixels where the damage lies in what JPEG
carries no check for, counted apart (`pixels`): the entropy-coded data, the quantisation tables (DQT) and
the Huffman tables (DHT). A frame header, scan header or restart interval changed without a word fails.
"""

import warnings
import zlib
from collections import Counter

import cv2
import numpy as np
import pytest
from fuzz_util import damaged, record

from pingpong.io.jpeg import MAX_PIXELS, SOS, _markers
from pingpong.twin import render

SUMMARY = "test_fuzz_jpeg:frame_summary"
EXAMPLES = 300  # random damages per decoder; both run in about a second
UNCHECKED = (0xDB, 0xC4)  # DQT, DHT: tables whose values change pixels, not the stream's structure
BAND = (40, 56)  # the rows a tracked ball's window would ask for


def frame_summary(path, rows=None):
    """The frame's shape and pixels (CRC), or None; a reason warns, naming the file."""
    from pathlib import Path

    from pingpong.io.jpeg import decode_jpeg, decode_jpeg_rows

    data = Path(path).read_bytes()
    image, reason = decode_jpeg(data) if rows is None else decode_jpeg_rows(data, *rows)
    if reason:
        warnings.warn(f"{path}: frame marked bad: {reason}", stacklevel=1)
    return None if image is None else (image.shape, zlib.crc32(image.tobytes()))


def twin_frame() -> bytes:
    """A 160x120 q90 frame with a restart marker per MCU row, as the twin's cameras write."""
    rng = np.random.default_rng(0)
    image = rng.uniform(0, 255, (120, 160, 3)).astype(np.float32)
    return render.encode_jpeg(cv2.GaussianBlur(image, (0, 0), 3).astype(np.uint8), 90)


def region(data: bytes, offset: int) -> str:
    """'pixels' where a byte at `offset` lies in data JPEG has no check for (module docstring), else
    'header'."""
    segments = list(_markers(data))
    sos = next(i for marker, i in segments if marker == SOS)
    if offset >= sos + 2 + int.from_bytes(data[sos + 2:sos + 4], "big"):
        return "pixels"  # the entropy-coded data
    holding = [(marker, i) for marker, i in segments if i <= offset]
    if holding and holding[-1][0] in UNCHECKED and offset >= holding[-1][1] + 4:
        return "pixels"  # a table's values, past its marker and length
    return "header"


def classify(result, path, original: bytes, bad: bytes, expected) -> str:
    outcome = result.outcome(path, expected)
    if outcome != "silent_wrong":
        return outcome
    offset = next((k for k, (a, b) in enumerate(zip(original, bad, strict=False)) if a != b),
                  min(len(original), len(bad)))
    return "pixels" if region(original, offset) == "pixels" else "lie"


@pytest.mark.parametrize("rows", [None, BAND], ids=["whole", "rows"])
def test_fuzz_jpeg(reader, tmp_path, rows):
    data = twin_frame()
    original = tmp_path / "original.jpg"
    original.write_bytes(data)
    expected = reader.call(SUMMARY, original, rows)
    assert expected.kind == "returned" and not expected.warned
    rng = np.random.default_rng(37)
    outcomes = []
    for _ in range(EXAMPLES):
        bad = damaged(data, rng)[1]
        path = tmp_path / "frame.jpg"
        path.write_bytes(bad)
        outcomes.append(classify(reader.call(SUMMARY, path, rows), path, data, bad, expected.value))
    counts = Counter(outcomes)
    pixels = counts.pop("pixels", 0)
    name = "jpeg whole (decode_jpeg)" if rows is None else "jpeg rows (decode_jpeg_rows)"
    table = record(name, [("silent_wrong" if o == "pixels" else o) for o in outcomes])
    assert counts["lie"] == 0 and table["crash"] == table["hang"] == table["unclear"] == 0, (counts, pixels)
    assert table["warning"] > EXAMPLES // 3


def with_size(data: bytes, width: int, height: int) -> bytes:
    """`data` with its frame header stating width x height."""
    sof = next(i for marker, i in _markers(data) if marker in (0xC0, 0xC1, 0xC2))
    return data[:sof + 5] + height.to_bytes(2, "big") + width.to_bytes(2, "big") + data[sof + 9:]


def progressive_frame() -> bytes:
    image = np.full((120, 160, 3), 128, np.uint8)
    return cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])[1].tobytes()


@pytest.mark.parametrize("rows", [None, BAND], ids=["whole", "rows"])
@pytest.mark.parametrize(("frame", "width", "height", "reason"), [
    (twin_frame, 30000, 30000, "frame header states 30000x30000 pixels, more than the 64 Mpx cap"),
    (progressive_frame, 30000, 30000, "frame header states 30000x30000 pixels, more than the 64 Mpx cap"),
    (twin_frame, 4000, 4000, "frame header states 4000x4000 pixels (750000 blocks, at least 187500 bytes"),
    (twin_frame, 160, 4000, "frame header states 160x4000 pixels"),
], ids=["baseline over the cap", "progressive over the cap", "baseline beyond its stream", "tall"])
def test_a_header_stating_a_huge_frame_is_refused_before_decoding(reader, tmp_path, frame, width, height,
                                                                 reason, rows):
    """Issue 37: a header claiming 30000 x 30000 decoded for 12 s into 5.3 GB."""
    assert width * height > MAX_PIXELS or frame is twin_frame
    path = tmp_path / "huge.jpg"
    path.write_bytes(with_size(frame(), width, height))
    result = reader.call(SUMMARY, path, rows)
    assert result.outcome(path, None) == "warning" and result.value is None
    assert reason in result.warned[0]
