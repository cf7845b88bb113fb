"""Lab data whose OptiTrack poses come as a Motive CSV export instead of the MCAP stream: the
calibration and paddle stages read it (time from the take's start plus the configured offset) and
give the paddle table of the stream."""

import shutil

import numpy as np
import pandas as pd
import pytest
from test_paddle_resample import swing, write_motive_csv
from workflow_util import copy_checkout, snakemake, write_config

from pingpong.io.mcap_io import read_optitrack
from pingpong.io.optitrack import OptitrackError, read_motive_csv


def mcap_to_motive_csv(mcap, csv) -> int:
    """The stream's bodies on one frame grid (the union of their times to the microsecond, the export's
    resolution), as a Motive export; returns the camera-clock time (ns) of the take's first frame."""
    bodies = read_optitrack(mcap)
    for body in bodies.values():
        body["time_ns"] = body["time_ns"].round(-3)
    times = np.unique(np.concatenate([b["time_ns"].to_numpy() for b in bodies.values()]))
    columns, lost = {}, {}
    for name, body in bodies.items():
        rows = body.set_index("time_ns").reindex(times)
        lost[name] = rows["x"].isna().to_numpy()
        columns[name] = (rows[["x", "y", "z"]].to_numpy(), rows[["qx", "qy", "qz", "qw"]].to_numpy())
    write_motive_csv(csv, (times - times[0]) / 1e9, columns, lost)
    return int(times[0])


@pytest.mark.slow
def test_paddles_from_a_motive_csv_equal_those_from_the_stream(tiny_run, tmp_path):
    root = copy_checkout(tmp_path)
    shutil.copytree(tiny_run / "raw/calibration", root / "raw/calibration")
    session = root / "raw/sessions/s00"
    shutil.copytree(tiny_run / "raw/sessions/s00", session, ignore=shutil.ignore_patterns("optitrack.mcap"))
    start = mcap_to_motive_csv(tiny_run / "raw/sessions/s00/optitrack.mcap", session / "optitrack.csv")
    cameras = sorted(p.stem for p in session.glob("cam*.mcap"))
    write_config(root, {"source": "lab", "lab": {"sessions": ["s00"], "cameras": cameras,
                                                 "optitrack_format": "motive_csv",
                                                 "motive_take_start_ns": {"s00": start}}})
    snakemake(root, "interim/paddle/s00.parquet")
    ours, stream = (pd.read_parquet(r / "interim/paddle/s00.parquet") for r in (root, tiny_run))
    pd.testing.assert_series_equal(ours["time_ns"], stream["time_ns"])
    # the same gaps, but the CSV's times to the microsecond may move a gap's edge by one frame (one frame
    # of 13,872 on the tiny run of 2026-12-02)
    valid = stream["valid"].to_numpy()
    edge = np.zeros(len(valid), bool)
    for _, rows in stream.groupby("player"):
        k = rows.index.to_numpy()
        change = np.flatnonzero(np.diff(valid[k])) if len(k) > 1 else np.array([], int)
        edge[k[change]] = edge[k[change + 1]] = True
    differ = ours["valid"].to_numpy() != valid
    assert not (differ & ~edge).any() and differ.sum() <= 0.001 * len(valid), np.flatnonzero(differ)
    both = (ours["valid"] & stream["valid"]).to_numpy()
    numbers = ours.columns.drop(["time_ns", "player", "valid"])
    position = [c for c in numbers if c in ("px", "py", "pz")]
    # the CSV holds quaternions to 6 decimals and times to the microsecond: 1e-5 of a rotation entry, and a
    # position off by the paddle's speed times 1 us. The speed is the stream's fastest frame-to-frame motion
    # (92.8 m/s on the tiny run of 2026-12-02, jumps across tracking gaps included: an upper bound)
    rotation = numbers.drop(position)
    np.testing.assert_allclose(ours[rotation][both], stream[rotation][both], atol=2e-5)
    speed = max(np.nanmax(np.linalg.norm(np.diff(g[position].to_numpy(), axis=0), axis=1)
                          / (np.diff(g["time_ns"].to_numpy()) / 1e9)) for _, g in stream.groupby("player"))
    assert np.isfinite(speed)
    np.testing.assert_allclose(ours[position][both], stream[position][both], atol=2e-5 + 1e-6 * speed)


# ---- a damaged export (issue 37): an error or a warning naming the file and the line, never silence


def motive_lines(tmp_path) -> tuple:
    """A 10-frame export of one body; its lines (data from line 8, frame k on line 8 + k)."""
    path = tmp_path / "take.csv"
    time_s = np.arange(10) / 240
    position, quaternion = swing(time_s)
    write_motive_csv(path, time_s, {"Paddle": (position, quaternion)}, {"Paddle": np.zeros(10, bool)})
    return path, path.read_text().split("\n")


def cell(line: str, column: int, text: str) -> str:
    cells = line.split(",")
    cells[column] = text
    return ",".join(cells)


@pytest.mark.parametrize("edit, message", [
    (lambda lines: lines.__setitem__(12, cell(lines[12], 1, "0.016000")),
     r"line 13: time 0\.016000 s does not follow line 12's 0\.016667 s; expected increasing times"),
    (lambda lines: lines.__setitem__(12, cell(lines[12], 1, "0.016667")),
     r"line 13: time 0\.016667 s does not follow line 12's 0\.016667 s"),
    (lambda lines: lines.__setitem__(9, cell(lines[9], 6, "nan")),
     r"line 10: 'nan' in column 7 is not finite; expected a finite number"),
    (lambda lines: lines.__setitem__(9, cell(lines[9], 3, "-inf")),
     r"line 10: '-inf' in column 4 is not finite"),
    (lambda lines: lines.__setitem__(9, cell(lines[9], 1, "1e400")),
     r"line 10: '1e400' in column 2 is not finite"),
    (lambda lines: lines.__setitem__(9, cell(lines[9], 0, "2.5")), r"line 10, column 1: frame '2\.5'"),
    (lambda lines: lines.__setitem__(9, lines[9] + "9" * 200_000),  # the csv module's own error
     r"line 10: field larger than field limit \(131072\); expected a Motive CSV export"),
])
def test_a_damaged_motive_row_is_an_error_naming_file_and_line(tmp_path, edit, message):
    path, lines = motive_lines(tmp_path)
    edit(lines)
    path.write_text("\n".join(lines))
    with pytest.raises(OptitrackError, match=r"take\.csv: " + message):
        read_motive_csv(path)


def test_a_motive_export_that_is_not_utf8(tmp_path):
    path, lines = motive_lines(tmp_path)
    path.write_bytes("\n".join(lines).encode().replace(b"0.012500", b"0.01\xb400"))
    with pytest.raises(OptitrackError, match=r"take\.csv: byte \d+ is not UTF-8 .*expected a Motive CSV"):
        read_motive_csv(path)


@pytest.mark.parametrize("row, message", [
    (11, r"take\.csv: line 11: frame 4 follows frame 2; expected consecutive frames"),
    (17, r"take\.csv: 9 rows of frames, its header declares 10 \(Total Exported Frames\)"),
])
def test_a_deleted_motive_row_warns(tmp_path, row, message):
    path, lines = motive_lines(tmp_path)
    del lines[row - 1]
    path.write_text("\n".join(lines))
    with pytest.warns(UserWarning, match=message):
        poses = read_motive_csv(path)["Paddle"]
    assert len(poses) == 9


def test_a_quaternion_not_of_unit_length_is_set_lost(tmp_path):
    path, lines = motive_lines(tmp_path)
    lines[9] = cell(lines[9], 2, str(float(lines[9].split(",")[2]) + 0.01))  # one digit of qx changed
    path.write_text("\n".join(lines))
    with pytest.warns(UserWarning, match=r"take\.csv: line 10: rigid body 'Paddle' has pose .*expected all "
                                         r"seven cells and a unit quaternion \(1 such rows, set lost\)"):
        poses = read_motive_csv(path)["Paddle"]
    assert poses.iloc[2, 1:].isna().all() and poses.drop(index=2).notna().all().all()
