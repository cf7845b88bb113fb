"""JPEG decoding that reports damage: the BGR image and the complaint that libjpeg writes and cv2 drops.

cv2.imdecode returns an image for many damaged JPEGs: libjpeg fills what it cannot decode (zeros for
missing entropy-coded data, so the blocks after a flipped byte shift colour and place) and writes its
warning ("Corrupt JPEG data: ...", "Premature end of JPEG file") with fprintf to the process's file
descriptor 2, which neither the caller nor Python's sys.stderr redirection sees. `decode_jpeg` points
fd 2 at a temporary file for the length of the decode and returns what was written there as the
reason; a JPEG without its end-of-image marker (truncated) is reported even where the decoder pads it
without a word.

A damaged frame comes back with its image (what the decoder made of it, for a viewer) and a non-empty
reason: a caller that measures pixels must treat any reason as a damaged frame and not measure it.

Not every damage is caught: JPEG has no checksum, and libjpeg complains only where the damaged data
no longer parse (a Huffman code that fits no table, data left over or missing at a marker). Of 60
random single-byte flips in the entropy-coded data of a 1440x1080 twin frame, 33 drew a complaint and
27 decoded silently to other pixels. What comes back clean is what libjpeg accepted; mcap_io's CRC
check of the MCAP chunks is what catches damage in transit.

While a decode runs, anything any thread writes to fd 2 lands in that decode's reason (and is not
shown): decodes hold a lock among themselves, and the decode itself takes milliseconds.
"""

import atexit
import os
import tempfile
import threading

import cv2
import numpy as np

from pingpong.common.stderr import fd2_onto

REDUCED_FLAGS = {1: cv2.IMREAD_COLOR, 2: cv2.IMREAD_REDUCED_COLOR_2, 4: cv2.IMREAD_REDUCED_COLOR_4,
                 8: cv2.IMREAD_REDUCED_COLOR_8}
SOI, EOI = b"\xff\xd8", b"\xff\xd9"  # start and end of image markers
PADDING = b"\x00\xff"  # bytes some cameras append after the end of image
_LOCK = threading.Lock()
_capture = None  # (pid, file) of this process's capture file: a forked child makes its own


def _capture_fd() -> int:
    """The descriptor of this process's capture file, made on first use (a fork would share its offset)."""
    global _capture
    if _capture is None or _capture[0] != os.getpid():
        _capture = os.getpid(), tempfile.TemporaryFile()
        atexit.register(_capture[1].close)
    return _capture[1].fileno()


def _imdecode_capturing(data: bytes, flag: int) -> tuple[np.ndarray | None, list[str]]:
    """(cv2.imdecode's image or None, the lines the decoder wrote on fd 2 and its exception, if any)."""
    with _LOCK:
        capture = _capture_fd()
        image, raised = None, []
        with fd2_onto(capture):
            try:
                image = cv2.imdecode(np.frombuffer(data, np.uint8), flag)
            except cv2.error as err:
                raised = [f"does not decode ({str(err).strip()})"]
        written = os.lseek(capture, 0, os.SEEK_CUR)  # fd 2 shared the capture file's offset
        text = ""
        if written:
            os.lseek(capture, 0, os.SEEK_SET)  # read from the start, then empty it for the next decode
            text = os.read(capture, written).decode("utf-8", "replace")
            os.ftruncate(capture, 0)
            os.lseek(capture, 0, os.SEEK_SET)
    return image, [line.strip() for line in text.splitlines() if line.strip()] + raised


def decode_jpeg(data: bytes, reduction: int = 1) -> tuple[np.ndarray | None, str]:
    """(BGR image, '' when clean or why it is damaged) of JPEG bytes; None where nothing decodes.

    reduction 2, 4 or 8: the image at 1/reduction of the full size, scaled by libjpeg in the DCT (the
    entropy decoding, most of the cost at q90, stays; the inverse DCT and colour conversion shrink).
    """
    if reduction not in REDUCED_FLAGS:
        raise ValueError(f"reduction {reduction!r}: expected one of {sorted(REDUCED_FLAGS)}")
    if not data.startswith(SOI):
        return None, f"{len(data)} bytes, not a JPEG (no start-of-image marker)" if data else "empty buffer"
    image, reasons = _imdecode_capturing(data, REDUCED_FLAGS[reduction])
    if image is None and not reasons:
        reasons.append(f"{len(data)} bytes do not decode")
    if not (data.endswith(EOI) or data.rstrip(PADDING).endswith(EOI)):
        reasons.append("no end-of-image marker (truncated)")
    return image, "; ".join(reasons)
