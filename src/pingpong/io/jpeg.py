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

Row bands (`decode_jpeg_rows`): where a JPEG has a restart marker after every MCU row (the DRI
interval one row of MCUs, cjpeg's `-restart 1`; what the twin's cameras write), each row is entropy
coded on its own, so the rows around a tracked ball decode alone: the header with the band's height,
the band's segments with their markers renumbered, and an end-of-image marker make a JPEG of just
those rows, whose pixels are those of the full decode (tests/test_jpeg.py compares them). Not with
vertical chroma subsampling (4:2:0): libjpeg's upsampling blends chroma rows across the band's edges.
Damage outside the band goes unseen unless it breaks the markers (a missing, stray or out-of-sequence
one): then the frame decodes whole. A 9-row band of a 480x360 twin frame decodes in ~0.3 ms, the
whole frame in ~0.9 ms (benchmarks/bench_detection.py: detection 1.37x the frames per second).

Not every damage is caught: JPEG has no checksum, and libjpeg complains only where the damaged data
no longer parse (a Huffman code that fits no table, data left over or missing at a marker). Of 60
random single-byte flips in the entropy-coded data of a 1440x1080 twin frame, 33 drew a complaint and
27 decoded silently to other pixels. What comes back clean is what libjpeg accepted; mcap_io's CRC
check of the MCAP chunks is what catches damage in transit.

A header is checked before anything decodes: libjpeg believes the size a frame header (SOF) states and
decodes a 30000 x 30000 header on a short stream for 12 s into 5.3 GB, padding the missing data. A frame
of more than `MAX_PIXELS` is refused, and a baseline (Huffman, sequential) one whose stream is shorter
than its blocks can be (each 8x8 block codes at least a DC and an end-of-block symbol, 2 bits) is refused
as truncated or misstated; progressive and arithmetic-coded frames can code runs of empty blocks in a few
bits, so for them the pixel cap alone bounds the work.

While a decode runs, anything any thread writes to fd 2 lands in that decode's reason (and is not
shown): decodes hold a lock among themselves, and the decode itself takes milliseconds.
"""

import atexit
import os
import re
import tempfile
import threading

import cv2
import numpy as np

from pingpong.common.stderr import fd2_onto

REDUCED_FLAGS = {1: cv2.IMREAD_COLOR, 2: cv2.IMREAD_REDUCED_COLOR_2, 4: cv2.IMREAD_REDUCED_COLOR_4,
                 8: cv2.IMREAD_REDUCED_COLOR_8}
SOI, EOI = b"\xff\xd8", b"\xff\xd9"  # start and end of image markers
SOF_BASELINE, DRI, SOS = (0xC0, 0xC1), 0xDD, 0xDA  # frame headers a row band can be cut from; markers
RST = re.compile(rb"\xff[\xd0-\xd7]")  # in entropy-coded data 0xFF is stuffed (0xFF00) unless a marker
PADDING = b"\x00\xff"  # bytes some cameras append after the end of image
MAX_PIXELS = 64_000_000  # a frame header may state at most 64 Mpx (a 4K camera's frame is 8.3 Mpx)
SOF_ANY = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}  # frame headers (C4, C8, CC: DHT, JPG, DAC)
NO_LENGTH = frozenset(range(0xD0, 0xDA)) | {0x01}  # RSTn, SOI, EOI, TEM: markers without a length
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


def _markers(data: bytes):
    """(marker, offset of its 0xFF) of the header's segments up to and with the first SOS, read as libjpeg
    reads them: bytes between segments are skipped to the next 0xFF, fill bytes (0xFF 0xFF) too."""
    i = 2
    while True:
        i = data.find(b"\xff", i)
        while 0 <= i < len(data) - 1 and data[i + 1] in (0x00, 0xFF):  # stuffed or fill byte: not a marker
            i = data.find(b"\xff", i + 1)
        if i < 0 or i + 1 >= len(data):
            return
        marker = data[i + 1]
        yield marker, i
        if marker == SOS or marker == 0xD9:
            return
        i += 2 if marker in NO_LENGTH else 2 + int.from_bytes(data[i + 2:i + 4], "big")


def _ceil(a: int, b: int) -> int:
    return -(a // -b)


def header_problem(data: bytes) -> str:
    """'' or why the first frame header must not be decoded: more than MAX_PIXELS, or (baseline) more
    blocks than the stream's bytes can code (module docstring)."""
    sof = next((i for marker, i in _markers(data) if marker in SOF_ANY), None)
    if sof is None or sof + 10 > len(data):
        return ""  # no frame header: libjpeg refuses such a stream by itself
    height, width = int.from_bytes(data[sof + 5:sof + 7], "big"), int.from_bytes(data[sof + 7:sof + 9], "big")
    if width * height > MAX_PIXELS:
        return f"frame header states {width}x{height} pixels, more than the {MAX_PIXELS / 1e6:g} Mpx cap"
    factors = data[sof + 11:sof + 10 + 3 * data[sof + 9]:3]  # per component: horizontal << 4 | vertical
    if data[sof + 1] not in SOF_BASELINE or not factors or min(f >> 4 for f in factors) == 0 \
            or min(f & 15 for f in factors) == 0:
        return ""  # progressive or arithmetic (no lower bound on its length), or a header libjpeg refuses
    h_max, v_max = max(f >> 4 for f in factors), max(f & 15 for f in factors)
    blocks = sum(_ceil(_ceil(width * (f >> 4), h_max), 8) * _ceil(_ceil(height * (f & 15), v_max), 8)
                 for f in factors)  # each component's 8x8 blocks, subsampled where its factors are smaller
    after = len(data) - sof
    if after < blocks / 4:
        return (f"frame header states {width}x{height} pixels ({blocks} blocks, at least {blocks // 4} bytes "
                f"coded) but only {after} bytes follow it: truncated, or a damaged header")
    return ""


def decode_jpeg(data: bytes, reduction: int = 1) -> tuple[np.ndarray | None, str]:
    """(BGR image, '' when clean or why it is damaged) of JPEG bytes; None where nothing decodes.

    reduction 2, 4 or 8: the image at 1/reduction of the full size, scaled by libjpeg in the DCT (the
    entropy decoding, most of the cost at q90, stays; the inverse DCT and colour conversion shrink).
    """
    if reduction not in REDUCED_FLAGS:
        raise ValueError(f"reduction {reduction!r}: expected one of {sorted(REDUCED_FLAGS)}")
    if not data.startswith(SOI):
        return None, f"{len(data)} bytes, not a JPEG (no start-of-image marker)" if data else "empty buffer"
    problem = header_problem(data)
    if problem:
        return None, problem
    image, reasons = _imdecode_capturing(data, REDUCED_FLAGS[reduction])
    if image is None and not reasons:
        reasons.append(f"{len(data)} bytes do not decode")
    if not (data.endswith(EOI) or data.rstrip(PADDING).endswith(EOI)):
        reasons.append("no end-of-image marker (truncated)")
    return image, "; ".join(reasons)


def _row_segments(data: bytes) -> tuple[int, int, int, list[int], list[int]] | None:
    """(SOF offset, image height, MCU height, segment starts, segment ends) of a baseline JPEG without
    vertical chroma subsampling and with one restart interval per MCU row; None for any other JPEG."""
    i, sof, interval = 2, None, 0
    while i + 4 <= len(data) and data[i] == 0xFF:
        marker, length = data[i + 1], int.from_bytes(data[i + 2:i + 4], "big")
        if marker in SOF_BASELINE:
            sof = i
        elif marker == DRI:
            interval = int.from_bytes(data[i + 4:i + 6], "big")
        elif marker == SOS:
            break
        i += 2 + length
    else:
        return None
    if sof is None or not interval:
        return None
    height, width = int.from_bytes(data[sof + 5:sof + 7], "big"), int.from_bytes(data[sof + 7:sof + 9], "big")
    n = data[sof + 9]
    factors = data[sof + 11:sof + 10 + 3 * n:3]  # per component: horizontal << 4 | vertical
    mcu_width, mcu_height = 8 * max(f >> 4 for f in factors), 8 * max(f & 15 for f in factors)
    one_scan = data[i + 4] == n  # a baseline JPEG may also code its components in separate scans
    if interval != -(-width // mcu_width) or len({f & 15 for f in factors}) != 1 or not one_scan:
        return None
    start = i + 2 + int.from_bytes(data[i + 2:i + 4], "big")
    markers = list(RST.finditer(data, start))
    rows = -(-height // mcu_height)
    if len(markers) != rows - 1 or any(m.group()[1] != 0xD0 + k % 8 for k, m in enumerate(markers)):
        return None
    end = data.rfind(EOI)
    return sof, height, mcu_height, [start] + [m.end() for m in markers], [m.start() for m in markers] + [end]


def decode_jpeg_rows(data: bytes, first_row: int, end_row: int) -> tuple[np.ndarray | None, str]:
    """decode_jpeg's (image, reason) with only the MCU rows holding pixel rows [first_row, end_row)
    decoded, the other rows zero; the whole image where the JPEG has no restart marker per MCU row
    (module docstring). Damage outside those rows goes unseen unless it breaks the markers."""
    index = _row_segments(data) if data.startswith(SOI) and data.rstrip(PADDING).endswith(EOI) else None
    if index is None or header_problem(data):  # decode_jpeg says what the header's problem is
        return decode_jpeg(data)
    sof, height, mcu_height, starts, ends = index
    first = min(max(first_row, 0) // mcu_height, len(starts) - 1)
    end = max(min(-(-end_row // mcu_height), len(starts)), first + 1)
    band_height = min(end * mcu_height, height) - first * mcu_height
    parts = [data[:sof + 5], band_height.to_bytes(2, "big"), data[sof + 7:starts[0]]]
    for k, row in enumerate(range(first, end)):
        if k:
            parts.append(bytes((0xFF, 0xD0 + (k - 1) % 8)))
        parts.append(data[starts[row]:ends[row]])
    parts.append(EOI)
    band, reasons = _imdecode_capturing(b"".join(parts), cv2.IMREAD_COLOR)
    if band is None:
        return None, "; ".join(reasons) or f"{len(data)} bytes do not decode"
    image = np.zeros((height, band.shape[1], 3), np.uint8)
    image[first * mcu_height:first * mcu_height + band_height] = band
    return image, "; ".join(reasons)
