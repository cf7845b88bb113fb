"""OptiTrack poses fuzzed (issue 37): the MCAP stream and a Motive CSV export, each damaged input read in a
forked child (tests/fuzz_util.py). Allowed: an error of the reader naming the file, a warning naming it,
or the undamaged poses; silently changed poses only in a Motive CSV where one text number changed into
another plausible one (the format carries no check), counted apart."""

import numpy as np
import pytest
from fuzz_util import damaged, record
from test_paddle_resample import swing, write_motive_csv

from pingpong.io.mcap_io import OptitrackWriter
from pingpong.io.optitrack import OptitrackError, read_optitrack_poses

SUMMARY = "test_fuzz_optitrack:poses_summary"
EXAMPLES = 150
T0 = 1_700_000_000_000_000_000


def poses_summary(path) -> dict:
    """Every body's rows (time_ns, x, y, z, qx, qy, qz, qw), a lost value as None."""
    from pingpong.io.optitrack import read_optitrack_poses

    bodies = read_optitrack_poses(path, take_start_ns=T0)
    return {name: tuple(tuple(None if np.isnan(v) else float(v) for v in row)
                        for row in frame.to_numpy(dtype=float))
            for name, frame in sorted(bodies.items())}


def one_row_changed(value: dict, expected: dict) -> bool:
    """The same bodies and rows, differing in one row at most: one text number of the export changed."""
    if value.keys() != expected.keys() or any(len(value[b]) != len(expected[b]) for b in value):
        return False
    rows = {n for b in value for n, (a, e) in enumerate(zip(value[b], expected[b], strict=True)) if a != e}
    return len(rows) <= 1


def motive_csv(path, n: int = 60):
    time_s = np.arange(n) / 240
    position, quaternion = swing(time_s)
    lost = np.zeros(n, bool)
    lost[20:25] = True
    write_motive_csv(path, time_s, {"PaddleRed": (position, quaternion),
                                    "PaddleBlack": (position[::-1] + 0.5, quaternion[::-1])},
                     {"PaddleRed": np.zeros(n, bool), "PaddleBlack": lost})
    return path


def optitrack_mcap(path, n: int = 100):
    position, quaternion = swing(np.arange(n) / 240)
    with OptitrackWriter(path) as writer:
        for k in range(n):
            t = T0 + k * 4_166_667
            writer.add("paddle_A", t, position[k], quaternion[k])
            if k % 3 == 0:
                writer.add("table_marker_0", t, np.array([0.5, 0.0, 1.0]), np.array([0.0, 0.0, 0.0, 1.0]))
    return path


def fuzz(reader, original, cases, name: str, text: bool) -> tuple[dict, list]:
    undamaged = reader.call(SUMMARY, original)
    assert undamaged.kind == "returned" and not undamaged.warned, undamaged
    expected = undamaged.value
    outcomes, bad = [], []
    for n, (kind, data) in enumerate(cases):
        path = original.with_name(f"damaged{n}{original.suffix}")
        path.write_bytes(data)
        result = reader.call(SUMMARY, path)
        outcome = result.outcome(path, expected)
        if outcome == "silent_wrong" and not (text and one_row_changed(result.value, expected)):
            outcome = "lie"  # more than one text number changed, or rows lost, without a word
        outcomes.append(outcome)
        if outcome not in ("clean_error", "warning", "unaffected", "silent_wrong"):
            bad.append((n, kind, outcome, result.error[:300] or str(result.value)[:300]))
        path.unlink()
    return record(name, outcomes), bad


def test_fuzz_optitrack_mcap(reader, tmp_path):
    original = optitrack_mcap(tmp_path / "optitrack.mcap")
    data = original.read_bytes()
    rng = np.random.default_rng(37)
    counts, bad = fuzz(reader, original, [damaged(data, rng) for _ in range(EXAMPLES)], "optitrack mcap",
                       text=False)
    assert not bad, bad[:3]
    assert counts["silent_wrong"] == 0  # zstd chunks carry a CRC


def test_fuzz_motive_csv(reader, tmp_path):
    original = motive_csv(tmp_path / "take.csv")
    data = original.read_bytes()
    rng = np.random.default_rng(37)
    cases = [damaged(data, rng) for _ in range(EXAMPLES)]
    counts, bad = fuzz(reader, original, cases, "optitrack motive csv", text=True)
    assert not bad, bad[:3]
    # silent only where one text number became another plausible one (a digit of a position, say)
    assert counts["silent_wrong"] <= 0.2 * EXAMPLES


# Issue 48: a held-out fuzz run's findings, each now an OptitrackError naming the file and the line


def test_two_motive_bodies_of_one_name_are_an_error(tmp_path):
    path = motive_csv(tmp_path / "take.csv")
    path.write_text(path.read_text().replace("PaddleBlack", "PaddleRed"))
    with pytest.raises(OptitrackError, match=r"take\.csv: the Name line: two rigid bodies named 'PaddleRed' "
                                             r"\(ID 1 and ID 2\); expected each name once"):
        read_optitrack_poses(path, take_start_ns=T0)


@pytest.mark.parametrize("seconds", ["1e300", "9300000000.0"])
def test_a_motive_time_beyond_int64_is_named(tmp_path, seconds):
    """An OverflowError naming no file: 1e300 s is infinite in ns, 9.3e9 s beyond int64's 292 years."""
    path = motive_csv(tmp_path / "take.csv")
    lines = path.read_text().splitlines(keepends=True)
    cells = lines[9].split(",")  # the third data line
    lines[9] = ",".join([cells[0], seconds, *cells[2:]])
    path.write_text("".join(lines))
    with pytest.raises(OptitrackError, match=rf"take\.csv: line 10: time '{seconds}' s in ns: \S+ does not "
                                             "fit int64"):
        read_optitrack_poses(path, take_start_ns=T0)


def test_a_take_start_that_overflows_the_times_is_named(tmp_path):
    """lab.motive_take_start_ns added to the take's times wrapped round to negative times without a word."""
    path = motive_csv(tmp_path / "take.csv")
    with pytest.raises(OptitrackError, match=r"take\.csv: the take's time 0 ns \+ lab.motive_take_start_ns "
                                             rf"{2**63} = {2**63} does not fit int64"):
        read_optitrack_poses(path, take_start_ns=2**63)
