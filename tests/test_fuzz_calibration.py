"""Calibration files fuzzed (issue 37): OpenCV FileStorage YAML and JSON, Anipose/Pose2Sim TOML.

Each damaged file goes through its reader (`read_opencv_calibration`, `read_anipose_toml`) in a forked
child (tests/fuzz_util.py): random damage (truncations, flipped bits, inserted or deleted bytes, empty
files) and wrong values put in place of a number (NaN, infinity, strings, booleans, nothing). Allowed: a
CalibrationFileError naming the file, or the undamaged cameras. Silent changes only where a text format
cannot tell, counted apart:
- `numbers`: the damage only changed digits, signs, points or separators, and what it made still reads
  as numbers that pass the checks (a plausible digit changed; a 5-coefficient distortion left with 4 only
  in a file of one camera, where no other camera's count tells: issue 48);
- `names`: only a camera's name changed (text; the calibration stage refuses a name the config lacks);
- `cut`: a truncation at a camera's end leaves the first cameras whole (YAML and TOML have no end
  marker; the stage refuses a configured camera that the file lacks).
"""

import re
from collections import Counter

import numpy as np
import pytest
from fuzz_util import damaged, record
from test_calibration_import import random_cameras

from pingpong.io.calibration_import import export_anipose_toml, export_opencv_yaml

SUMMARY = "test_fuzz_calibration:cameras_summary"
EXAMPLES = 300  # random damages per format; with the wrong values all formats run in about a second
WRONG = 100  # files with a wrong value in place of a number, per format
NUMERIC = set(b"0123456789.-+eE, \n\t")
NUMBER = re.compile(rb"(?<![\w.])-?\d+\.?\d*(?:[eE][-+]?\d+)?(?![\w.])")
WRONG_VALUES = {  # what each format writes for NaN, infinity, a string, a boolean, nothing
    "yaml": [b".nan", b".inf", b"-.inf", b'"1000"', b"true", b"", b"[]", b"{}"],
    "json": [b"NaN", b"Infinity", b'"1000"', b"true", b"null", b"", b"[]", b"{}"],
    "toml": [b"nan", b"inf", b"-inf", b'"1000"', b"true", b"", b"[]", b"{}"],
}


def cameras_summary(path, fmt: str) -> list[tuple]:
    """Each camera as (name, width, height, K, dist, R, t values) as the reader returns it."""
    from pingpong.io.calibration_import import read_anipose_toml, read_opencv_calibration

    read = read_anipose_toml if fmt == "toml" else read_opencv_calibration
    return [(c.name, c.width, c.height, *np.concatenate([c.K.ravel(), c.dist, c.R.ravel(), c.t]).tolist())
            for c in read(path, units="m")]


def changed_span(a: bytes, b: bytes) -> tuple[bytes, bytes]:
    """(the bytes of `a` that `b` replaced, what replaced them): between their common prefix and suffix."""
    p = 0
    while p < min(len(a), len(b)) and a[p] == b[p]:
        p += 1
    s = 0
    while s < min(len(a), len(b)) - p and a[-1 - s] == b[-1 - s]:
        s += 1
    return a[p:len(a) - s], b[p:len(b) - s]


def classify(result, path, original: bytes, damaged_bytes: bytes, expected) -> str:
    """The harness's outcome, a silent change split into what the format cannot tell (module docstring)
    and `lie` (never allowed)."""
    outcome = result.outcome(path, expected)
    if outcome != "silent_wrong":
        return outcome
    old, new = changed_span(original, damaged_bytes)
    got = result.value
    if set(old) <= NUMERIC and set(new) <= NUMERIC:
        return "numbers"
    if len(got) == len(expected) and all(a[1:] == b[1:] for a, b in zip(got, expected, strict=True)):
        return "names"
    if len(got) < len(expected) and got == expected[:len(got)] and original.startswith(damaged_bytes):
        return "cut"
    return "lie"


def rig_file(tmp_path, fmt: str):
    path = tmp_path / f"original.{fmt}"
    cameras = random_cameras(np.random.default_rng(11), 3)
    (export_anipose_toml if fmt == "toml" else export_opencv_yaml)(cameras, path)
    return path


def with_wrong_value(data: bytes, fmt: str, rng) -> bytes:
    """`data` with one of its numbers replaced by a value of WRONG_VALUES."""
    numbers = list(NUMBER.finditer(data))
    m = numbers[int(rng.integers(len(numbers)))]
    wrong = WRONG_VALUES[fmt][int(rng.integers(len(WRONG_VALUES[fmt])))]
    return data[:m.start()] + wrong + data[m.end():]


@pytest.mark.parametrize("fmt", ["yaml", "json", "toml"])
def test_fuzz_calibration(reader, tmp_path, fmt):
    original = rig_file(tmp_path, fmt)
    data = original.read_bytes()
    expected = reader.call(SUMMARY, original, fmt).value
    assert expected is not None and len(expected) == 3
    rng = np.random.default_rng(37)
    outcomes = []
    for i in range(EXAMPLES + WRONG):
        bad = damaged(data, rng)[1] if i < EXAMPLES else with_wrong_value(data, fmt, rng)
        path = tmp_path / f"calibration.{fmt}"
        path.write_bytes(bad)
        outcomes.append(classify(reader.call(SUMMARY, path, fmt), path, data, bad, expected))
    counts = Counter(outcomes)
    apart = {k: counts.pop(k, 0) for k in ("numbers", "names", "cut")}
    table = record(f"calibration {fmt}", [("silent_wrong" if o in apart else o) for o in outcomes])
    assert counts["lie"] == 0 and table["crash"] == table["hang"] == table["unclear"] == 0, (counts, apart)
    assert table["clean_error"] > EXAMPLES // 2  # most damage is refused, not read


MATRIX_HEADERS = [  # (what replaces camera 0's "cols: 3" / "rows: 3" / "dt: d" of its camera matrix)
    ("cols", b"-1"), ("cols", b"0"), ("cols", b"2147483647"), ("cols", b"100000000000"), ("cols", b"1e30"),
    ("cols", b"2"), ("cols", b"4"), ("cols", b"x"), ("cols", None), ("rows", b"-1"), ("rows", b"9"),
    ("rows", None), ("dt", b"u"), ("dt", b"i"), ("dt", b"c"), ("dt", b"3d"), ("dt", b"dd"), ("dt", None),
    ("data", None),
]


@pytest.mark.parametrize("fmt", ["yaml", "json"])
@pytest.mark.parametrize(("key", "value"), MATRIX_HEADERS)
def test_a_wrong_matrix_header_is_a_clean_error_never_a_crash(reader, tmp_path, fmt, key, value):
    """Issue 37: `cols: -1`, a huge or a missing `cols` corrupted the heap inside cv2's FileNode.mat()."""
    data = rig_file(tmp_path, fmt).read_bytes()
    quoted = fmt == "json"
    name = b'"%s": ' % key.encode() if quoted else key.encode() + b": "
    at = data.index(name, data.index(b"camera_matrix"))
    end = data.index(b"\n", at)
    if key == "data":
        end = data.index(b"]", at) + 1
    if value is None:
        line_start = data.rindex(b"\n", 0, at)
        bad = data[:line_start] + data[end:]
    else:
        text = b'"%s"' % value if quoted and key == "dt" else value
        bad = data[:at] + name + text + (b"," if quoted and data[end - 1:end] == b"," else b"") + data[end:]
    if quoted and value is None and key == "data":  # the comma before a removed last member
        bad = bad.replace(b'"d",\n            }', b'"d"\n            }')
    path = tmp_path / f"matrix.{fmt}"
    path.write_bytes(bad)
    result = reader.call(SUMMARY, path, fmt)
    assert result.outcome(path, None) == "clean_error", result
    # where FileStorage parses it (`cols: x` is not JSON, `dt: 3d` not YAML to it), the key is named
    assert "cameras[0]: key 'camera_matrix'" in result.error or "not a readable OpenCV" in result.error


# Issue 48: a held-out fuzz run's findings


DEEP = 200_000
NESTED = {"yaml": "%YAML:1.0\n---\ncameras: " + "[" * DEEP + "]" * DEEP + "\n",
          "json": '{"cameras": ' + "[" * DEEP + "]" * DEEP + "}",
          "toml": "[cam_0]\nmatrix = " + "[" * DEEP + "]" * DEEP + "\n"}


@pytest.mark.parametrize("fmt", ["yaml", "json", "toml"])
def test_a_file_nested_200000_deep_is_a_clean_error(reader, tmp_path, fmt):
    """Every parser's depth limit (FileStorage's own, tomllib's and json's RecursionError) is the reader's
    error naming the file."""
    path = tmp_path / f"calibration.{fmt}"
    path.write_text(NESTED[fmt])
    result = reader.call(SUMMARY, path, fmt)
    assert result.outcome(path, None) == "clean_error", result
    assert "CalibrationFileError" in result.error and ("nested" in result.error.lower()), result.error


@pytest.mark.parametrize("fmt", ["yaml", "json", "toml"])
def test_a_value_deleted_from_any_array_is_a_clean_error(reader, tmp_path, fmt):
    """Each number of an exported rig deleted in turn, with its separator: never read as cameras (a TOML
    distortion one value short was, as a 4-coefficient model); where the file still parses, the error
    names the camera and the key."""
    data = rig_file(tmp_path, fmt).read_bytes()
    body = data.index(b"cameras") if fmt != "toml" else 0  # past the YAML header's version number
    path = tmp_path / f"short.{fmt}"
    for m in NUMBER.finditer(data, body):
        end = m.end() + len(re.match(rb"[, ]*", data[m.end():]).group())
        path.write_bytes(data[:m.start()] + data[end:])
        result = reader.call(SUMMARY, path, fmt)
        assert result.outcome(path, None) == "clean_error", (data[m.start() - 40:end], result)
        if "not valid TOML" not in result.error and "not a readable OpenCV" not in result.error:
            assert re.search(r"(\[cam_\d\]|cameras\[\d\]): keys? '", result.error), result.error
