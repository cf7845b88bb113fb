"""pingpong.io.jpeg.decode_jpeg: clean frames decode as cv2 decodes them, damaged ones say so, no leaks."""

import os
import re

import cv2
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from pingpong.io.jpeg import RST, decode_jpeg, decode_jpeg_rows, header_problem
from pingpong.twin import render

WIDTH, HEIGHT = 1440, 1080


@pytest.fixture(scope="module")
def clean() -> bytes:
    """A 1440x1080 q90 4:4:4 JPEG of smooth colour with sensor noise, as the twin's cameras write."""
    rng = np.random.default_rng(0)
    image = cv2.GaussianBlur(rng.uniform(0, 255, (HEIGHT, WIDTH, 3)).astype(np.float32), (0, 0), 6)
    image = (image - image.min()) * 255 / (image.max() - image.min()) + rng.normal(0, 2.0, image.shape)
    return render.encode_jpeg(np.clip(image, 0, 255).astype(np.uint8), 90)


def entropy_start(data: bytes) -> int:
    """Index of the first entropy-coded byte: after the start-of-scan marker and its header."""
    sos = data.index(b"\xff\xda")
    return sos + 2 + int.from_bytes(data[sos + 2:sos + 4], "big")


def stray_marker(data: bytes, fraction: float) -> bytes:
    """`data` with one byte corrupted `fraction` of the way into the entropy-coded data: the 0x00 that
    stuffs a 0xFF data byte turned into 0xD3, a restart marker out of sequence (the twin's frames have one
    per MCU row, D0..D7 in turn). A flipped byte elsewhere may draw no complaint (pingpong.io.jpeg's
    docstring); this one always does."""
    start = entropy_start(data)
    i = data.index(b"\xff\x00", start + int(fraction * (len(data) - start))) + 1
    return data[:i] + b"\xd3" + data[i + 1:]


@pytest.mark.parametrize("reduction", [1, 2, 4, 8])
def test_a_clean_jpeg_decodes_as_cv2_decodes_it(clean, reduction):
    image, reason = decode_jpeg(clean, reduction)
    flag = {1: cv2.IMREAD_COLOR, 2: cv2.IMREAD_REDUCED_COLOR_2, 4: cv2.IMREAD_REDUCED_COLOR_4,
            8: cv2.IMREAD_REDUCED_COLOR_8}[reduction]
    assert reason == ""
    np.testing.assert_array_equal(image, cv2.imdecode(np.frombuffer(clean, np.uint8), flag))
    assert image.shape == (HEIGHT // reduction, WIDTH // reduction, 3)


def test_padding_after_the_end_of_image_is_clean(clean):
    image, reason = decode_jpeg(clean + b"\x00" * 5)
    assert reason == "" and image.shape == (HEIGHT, WIDTH, 3)


@pytest.mark.parametrize("fraction", [0.1, 0.5, 0.9])
@pytest.mark.parametrize("reduction", [1, 4])
def test_a_corrupted_byte_in_the_entropy_coded_data_is_reported(clean, fraction, reduction):
    damaged = stray_marker(clean, fraction)
    assert len(damaged) == len(clean) and sum(a != b for a, b in zip(damaged, clean, strict=True)) == 1
    image, reason = decode_jpeg(damaged, reduction)
    assert "Corrupt JPEG data" in reason
    # cv2 alone makes a 'good' image of it, wrong from the damaged block on: the reason is all that tells
    repaired = cv2.imdecode(np.frombuffer(damaged, np.uint8), cv2.IMREAD_COLOR)
    assert repaired is not None and not np.array_equal(repaired, cv2.imdecode(np.frombuffer(clean, np.uint8),
                                                                                 cv2.IMREAD_COLOR))
    assert image is not None and image.shape == (HEIGHT // reduction, WIDTH // reduction, 3)


@pytest.mark.parametrize("keep", [0.5, 0.99, "all but the end-of-image marker"])
def test_a_truncated_jpeg_is_reported(clean, keep):
    cut = clean[:-2] if isinstance(keep, str) else clean[:int(keep * len(clean))]
    image, reason = decode_jpeg(cut)
    assert "no end-of-image marker (truncated)" in reason


@pytest.mark.parametrize("data", [b"", b"\xff\xd8 not a jpeg", b"\x89PNG\r\n\x1a\n not a jpeg either"],
                         ids=["empty", "garbage after a start marker", "png signature"])
def test_empty_and_non_jpeg_bytes_give_no_image_and_a_reason(data):
    image, reason = decode_jpeg(data)
    assert image is None and reason


def test_a_png_is_not_decoded_as_a_jpeg():
    ok, png = cv2.imencode(".png", np.zeros((8, 8, 3), np.uint8))
    assert ok
    assert decode_jpeg(png.tobytes()) == (None, f"{len(png)} bytes, not a JPEG (no start-of-image marker)")


def test_only_the_four_decoder_reductions(clean):
    with pytest.raises(ValueError, match="reduction 3"):
        decode_jpeg(clean, 3)


def test_the_decoders_complaint_does_not_leak_to_fd_2_and_fd_2_is_restored(clean, capfd):
    damaged = stray_marker(clean, 0.5)
    cv2.imdecode(np.frombuffer(damaged, np.uint8), cv2.IMREAD_COLOR)
    assert "Corrupt JPEG data" in capfd.readouterr().err  # where libjpeg writes it when nobody captures
    reasons = [decode_jpeg(damaged)[1] for _ in range(3)]
    assert all("Corrupt JPEG data" in r for r in reasons)
    assert len(set(reasons)) == 1  # each decode reports its own complaint, not the ones before
    assert decode_jpeg(clean)[1] == ""  # and nothing stale is left for the next one
    os.write(2, b"written on fd 2 after the decodes\n")
    out, err = capfd.readouterr()
    assert err == "written on fd 2 after the decodes\n" and out == ""


@given(first=st.integers(-50, HEIGHT - 1), length=st.integers(1, 400))
def test_a_band_of_rows_decodes_as_those_rows_of_the_whole_image(clean, first, length):
    assume(first + length > 0)  # rows in the image
    whole, _ = decode_jpeg(clean)
    band, reason = decode_jpeg_rows(clean, first, first + length)
    lo, hi = max(first, 0), min(first + length, HEIGHT)
    assert reason == "" and band.shape == whole.shape
    np.testing.assert_array_equal(band[lo:hi], whole[lo:hi])
    decoded = np.flatnonzero(band.any(axis=(1, 2)))  # whole MCU rows (8 px at 4:4:4) around them, no more
    assert decoded.min() >= lo // 8 * 8 and decoded.max() < -(-hi // 8) * 8


def test_the_twin_writes_a_restart_marker_per_mcu_row(clean):
    assert len(RST.findall(clean)) == HEIGHT // 8 - 1


def without_restart_markers(image: np.ndarray, chroma=cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444) -> bytes:
    return cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90, cv2.IMWRITE_JPEG_SAMPLING_FACTOR,
                                        chroma])[1].tobytes()


def test_restart_markers_change_no_pixel(clean):
    whole, _ = decode_jpeg(clean)
    np.testing.assert_array_equal(decode_jpeg(without_restart_markers(whole))[0],
                                  decode_jpeg(render.encode_jpeg(whole))[0])


@pytest.mark.parametrize("case", ["no restart markers", "4:2:0 chroma", "a restart marker missing",
                                  "a stray restart marker"])
def test_a_jpeg_without_a_restart_marker_per_row_decodes_whole_and_damage_still_tells(clean, case):
    whole, _ = decode_jpeg(clean)
    data = {"no restart markers": lambda: without_restart_markers(whole),
            "4:2:0 chroma": lambda: render.encode_jpeg(whole, chroma="420"),
            "a restart marker missing": lambda: clean.replace(b"\xff\xd3", b"", 1),
            "a stray restart marker": lambda: stray_marker(clean, 0.9)}[case]()
    image, reason = decode_jpeg_rows(data, 0, 8)
    whole_image, whole_reason = decode_jpeg(data)
    assert reason == whole_reason
    np.testing.assert_array_equal(image, whole_image)
    assert ("Corrupt JPEG data" in reason) == case.startswith("a ")


# --- the header checked before any decode (issue 37: a header claiming 30000 x 30000 decoded for 12 s into
# 5.3 GB) --------------------------------------------------------------------------------------------------

def with_size(data: bytes, width: int, height: int) -> bytes:
    sof = data.index(b"\xff\xc0")
    return data[:sof + 5] + height.to_bytes(2, "big") + width.to_bytes(2, "big") + data[sof + 9:]


@pytest.mark.parametrize(("width", "height", "reason"), [
    (30000, 30000, "frame header states 30000x30000 pixels, more than the 64 Mpx cap"),
    (8000, 8000, r"frame header states 8000x8000 pixels \(3000000 blocks, at least 750000 bytes coded\) but "
                 r"only \d+ bytes follow it: truncated, or a damaged header"),
])
def test_a_header_larger_than_the_cap_or_its_stream_is_refused_before_decoding(clean, monkeypatch, width,
                                                                                height, reason):
    def no_decode(*args):
        raise AssertionError("decoded")

    monkeypatch.setattr("pingpong.io.jpeg._imdecode_capturing", no_decode)
    data = with_size(clean, width, height)
    for image, why in [decode_jpeg(data), decode_jpeg(data, 8), decode_jpeg_rows(data, 0, 8)]:
        assert image is None and re.fullmatch(reason, why)


@settings(max_examples=40, deadline=None)
@given(width=st.integers(1, 700), height=st.integers(1, 700), chroma=st.sampled_from(["444", "420", "gray"]),
       optimize=st.booleans(), level=st.integers(0, 255))
def test_no_valid_baseline_frame_is_refused_by_its_header(width, height, chroma, optimize, level):
    """A flat frame (the fewest bits a block can take; optimised Huffman tables: 1-bit codes) of any size
    and subsampling passes the header's length check and decodes clean."""
    image = np.full((height, width, 3), level, np.uint8)
    params = [cv2.IMWRITE_JPEG_QUALITY, 50, cv2.IMWRITE_JPEG_OPTIMIZE, int(optimize)]
    if chroma == "gray":
        image = image[..., 0]
    else:
        params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, {"444": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444,
                                                      "420": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420}[chroma]]
    data = cv2.imencode(".jpg", image, params)[1].tobytes()
    assert header_problem(data) == ""
    decoded, reason = decode_jpeg(data)
    assert reason == "" and decoded.shape == (height, width, 3)
