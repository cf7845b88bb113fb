"""Paddle poses: slerp/linear resampling with gap marking, Motive CSV reading, OptiTrack-to-table fit."""

import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from pingpong.common.rigid import (
    apply_transform,
    fit_rigid_transform,
    invert_transform,
    make_transform,
    matrix_to_quat_xyzw,
    quat_xyzw_to_matrix,
)
from pingpong.frames import TABLE_HALF_LENGTH, TABLE_HALF_WIDTH
from pingpong.io.mcap_io import OptitrackWriter
from pingpong.io.optitrack import read_motive_csv, read_optitrack_poses
from pingpong.perception.calibration import fit_optitrack_to_table
from pingpong.perception.paddle import paddle_table, resample_poses, to_table_frame

OPTITRACK_NS = round(1e9 / 240)


def angle_deg(R_a: np.ndarray, R_b: np.ndarray) -> np.ndarray:
    return np.degrees(Rotation.from_matrix(np.swapaxes(R_a, -1, -2) @ R_b).magnitude())


def swing(time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A smooth known paddle motion: sinusoidal position (m), rotation at a constant 1 rev/s."""
    position = np.stack([0.4 * np.sin(2 * np.pi * time_s), -1.5 + 0.3 * np.cos(2 * np.pi * time_s + 0.3),
                         1.0 + 0.2 * np.sin(2 * np.pi * time_s + 1.0)], axis=1)
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    start = Rotation.from_euler("xyz", [0.4, -1.1, 2.0])
    rotation = start * Rotation.from_rotvec(2 * np.pi * time_s[:, None] * axis)
    return position, rotation.as_quat()


def test_slerp_midpoint_of_two_known_rotations():
    R0 = Rotation.from_euler("z", 10, degrees=True)
    R1 = Rotation.from_euler("z", 100, degrees=True)
    quats = np.stack([R0.as_quat(), -R1.as_quat()])  # the sign of a quaternion must not matter
    positions = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, -4.0]])
    pos, rot, valid = resample_poses(np.array([0, 10_000_000]), positions, quats,
                                     np.array([5_000_000, 2_500_000]))
    assert valid.all()
    np.testing.assert_allclose(rot[0], Rotation.from_euler("z", 55, degrees=True).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(rot[1], Rotation.from_euler("z", 32.5, degrees=True).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(pos, [[0.5, 1.0, -2.0], [0.25, 0.5, -1.0]], atol=1e-12)


def test_smooth_swing_from_240_to_100_hz():
    sample_ns = np.arange(0, 3 * 240) * OPTITRACK_NS + 123_456
    position, quats = swing(sample_ns / 1e9)
    target_ns = np.arange(1, 299) * 10_000_000
    pos, rot, valid = resample_poses(sample_ns, position, quats, target_ns)
    true_pos, true_quats = swing(target_ns / 1e9)
    assert valid.all()
    assert np.abs(pos - true_pos).max() < 1e-4  # 0.1 mm
    assert angle_deg(rot, quat_xyzw_to_matrix(true_quats)).max() < 0.05


def test_gaps_are_marked_not_filled():
    sample_ns = np.arange(0, 2 * 240) * OPTITRACK_NS
    position, quats = swing(sample_ns / 1e9)
    keep = np.ones(480, bool)
    keep[121:168] = False  # a 0.2 s occlusion: samples removed
    position[289:312] = np.nan  # a 0.1 s occlusion: NaN samples
    quats[217:219] = np.nan  # two lost samples: 12.5 ms < max_gap_s, bridged
    target_ns = np.arange(-5, 205) * 10_000_000
    pos, rot, valid = resample_poses(sample_ns[keep], position[keep], quats[keep], target_ns, max_gap_s=0.05)

    def in_gap(first_lost, last_lost):
        return (target_ns > sample_ns[first_lost - 1]) & (target_ns < sample_ns[last_lost + 1])

    expect_invalid = in_gap(121, 167) | in_gap(289, 311) | (target_ns < 0) | (target_ns > sample_ns[-1])
    np.testing.assert_array_equal(valid, ~expect_invalid)
    assert np.isnan(pos[~valid]).all() and np.isnan(rot[~valid]).all()
    assert np.isfinite(pos[valid]).all() and np.isfinite(rot[valid]).all()
    true_pos, _ = swing(target_ns[valid] / 1e9)
    assert np.abs(pos[valid] - true_pos).max() < 1e-3


def test_target_on_a_sample_beside_a_gap_is_valid():
    sample_ns = np.array([0, 10, 1_000_000_000])
    quats = np.tile([0.0, 0.0, 0.0, 1.0], (3, 1))
    targets = np.array([10, 11, 999_999_999, 1_000_000_000])
    _, _, valid = resample_poses(sample_ns, np.zeros((3, 3)), quats, targets)
    np.testing.assert_array_equal(valid, [True, False, False, True])


def test_unsorted_and_duplicated_samples_are_cleaned_with_a_warning():
    sample_ns = np.arange(0, 240) * OPTITRACK_NS
    position, quats = swing(sample_ns / 1e9)
    target_ns = np.arange(1, 99) * 10_000_000
    clean = resample_poses(sample_ns, position, quats, target_ns)
    order = np.random.default_rng(0).permutation(240)
    with pytest.warns(UserWarning, match="not sorted"):
        shuffled = resample_poses(sample_ns[order], position[order], quats[order], target_ns)
    # each copy right after its original, with a different position that must be ignored
    with_copies = np.argsort(np.r_[np.arange(240), [5, 9, 100]], kind="stable")
    copied_position = np.r_[position, position[[5, 9, 100]] + 1.0][with_copies]
    with pytest.warns(UserWarning, match="3 duplicated"):
        duplicated = resample_poses(np.r_[sample_ns, sample_ns[[5, 9, 100]]][with_copies], copied_position,
                                    np.r_[quats, quats[[5, 9, 100]]][with_copies], target_ns)
    for result in (shuffled, duplicated):
        for a, b in zip(result, clean, strict=True):
            np.testing.assert_array_equal(a, b)


def test_too_few_samples_gives_all_invalid():
    one_sample = (np.array([0]), np.zeros((1, 3)), np.array([[0, 0, 0, 1.0]]))
    pos, rot, valid = resample_poses(*one_sample, np.array([0, 5]))
    assert not valid.any() and np.isnan(pos).all() and np.isnan(rot).all()


def test_to_table_frame_matches_the_transform():
    rng = np.random.default_rng(1)
    R = Rotation.random(random_state=2).as_matrix()
    T = make_transform(R, [0.1, 2.0, -0.3])
    positions = rng.normal(size=(5, 3))
    positions[2] = np.nan
    rotations = Rotation.random(5, random_state=3).as_matrix()
    pos, rot = to_table_frame(positions, rotations, T)
    seen = [0, 1, 3, 4]
    np.testing.assert_allclose(pos[seen], positions[seen] @ R.T + [0.1, 2.0, -0.3], atol=1e-12)
    assert np.isnan(pos[2]).all()
    np.testing.assert_allclose(rot, R @ rotations, atol=1e-12)
    np.testing.assert_allclose(apply_transform(invert_transform(T), pos[[0]]), positions[[0]], atol=1e-12)


def test_quaternion_matrix_round_trip():
    quats = Rotation.random(50, random_state=4).as_quat()
    back = matrix_to_quat_xyzw(quat_xyzw_to_matrix(quats.reshape(5, 10, 4))).reshape(50, 4)
    np.testing.assert_allclose(np.abs(np.sum(back * quats, axis=1)), 1.0, atol=1e-12)
    assert (back[:, 3] >= 0).all()


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_points=st.integers(3, 20), offset=st.floats(-10, 10))
def test_kabsch_recovers_a_random_transform_exactly(seed, n_points, offset):
    rng = np.random.default_rng(seed)
    T_true = make_transform(Rotation.random(random_state=rng).as_matrix(), rng.normal(size=3) + offset)
    points = rng.uniform(-2, 2, (n_points, 3))
    T, rms = fit_rigid_transform(points, apply_transform(T_true, points))
    np.testing.assert_allclose(T, T_true, atol=1e-9)
    assert rms < 1e-9


def test_kabsch_with_marker_noise_within_a_millimetre():
    rng = np.random.default_rng(5)
    # markers on the table's corners, net posts and two lifted on stands, measured in the table frame
    corners = [[sx * TABLE_HALF_WIDTH, sy * TABLE_HALF_LENGTH, 0.0] for sx in (-1, 1) for sy in (-1, 1)]
    table = np.array(corners + [[-0.915, 0.0, 0.15], [0.915, 0.0, 0.15], [0.0, 1.0, 0.5], [0.0, -1.0, 0.5]])
    T_table_from_opti = make_transform(Rotation.from_euler("xz", [90, 30], degrees=True).as_matrix(),
                                       [0.5, -2.0, 1.1])
    optitrack = apply_transform(invert_transform(T_table_from_opti), table) + rng.normal(0, 3e-4, table.shape)
    T, rms = fit_optitrack_to_table(optitrack, table)
    assert 1e-4 < rms < 6e-4
    grid = np.stack(np.meshgrid(np.linspace(-0.8, 0.8, 5), np.linspace(-1.5, 1.5, 5), [0.0, 1.0]), -1)
    grid = grid.reshape(-1, 3)  # the table and the air above it
    opti_grid = apply_transform(invert_transform(T_table_from_opti), grid)
    assert np.linalg.norm(apply_transform(T, opti_grid) - grid, axis=1).max() < 1e-3


def test_fit_logs_the_residual(caplog):
    points = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    with caplog.at_level(logging.INFO, logger="pingpong.perception.calibration"):
        _, rms = fit_optitrack_to_table(points, points + [[0.002, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0]])
    assert f"4 markers: RMS residual {1e3 * rms:.2f} mm" in caplog.text


def test_kabsch_rejects_collinear_markers():
    line = np.outer(np.arange(4.0), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="non-collinear"):
        fit_rigid_transform(line, line)
    with pytest.raises(ValueError, match="non-collinear"):
        fit_rigid_transform(line[:2], line[:2])


# --- Motive CSV ------------------------------------------------------------------------------------

def write_motive_csv(path, time_s, bodies: dict, dropouts: dict) -> None:
    """A Motive 2.x 'Format Version 1.23' export in millimetres: per rigid body Rotation X Y Z W,
    Position X Y Z and Mean Marker Error, one Rigid Body Marker per body and an unlabelled marker."""
    type_row, name_row, id_row = ["", "Type"], ["", "Name"], ["", "ID"]
    comp_row, axis_row = ["", ""], ["Frame", "Time (Seconds)"]
    for n, name in enumerate(bodies):
        for comp, axes in (("Rotation", "XYZW"), ("Position", "XYZ"), ("Mean Marker Error", " ")):
            for ax in axes:
                type_row.append("Rigid Body")
                name_row.append(name)
                id_row.append(str(n + 1))
                comp_row.append(comp)
                axis_row.append(ax.strip())
        for comp, axes in (("Position", "XYZ"), ("Marker Quality", " ")):
            for ax in axes:
                type_row.append("Rigid Body Marker")
                name_row.append(f"{name}:Marker1")
                id_row.append(f"{n + 1}:1")
                comp_row.append(comp)
                axis_row.append(ax.strip())
    for ax in "XYZ":
        type_row.append("Marker")
        name_row.append("Unlabeled 1000")
        id_row.append("Marker 1000")
        comp_row.append("Position")
        axis_row.append(ax)
    lines = [
        "Format Version,1.23,Take Name,Rally 012,Take Notes,,Capture Frame Rate,240.000000,"
        "Export Frame Rate,240.000000,Capture Start Time,2024-03-14 02.15.09.123 PM,"
        f"Total Frames in Take,{len(time_s)},Total Exported Frames,{len(time_s)},Rotation Type,Quaternion,"
        "Length Units,Millimeters,Coordinate Space,Global",
        "",
        *(",".join(row) for row in (type_row, name_row, id_row, comp_row, axis_row)),
    ]
    for k, t in enumerate(time_s):
        cells = [str(k), f"{t:.6f}"]
        for name, (position_m, quats) in bodies.items():
            lost = dropouts[name][k]
            pose = [f"{v:.6f}" for v in quats[k]] + [f"{1e3 * v:.6f}" for v in position_m[k]] + ["0.000213"]
            cells += [""] * 8 if lost else pose
            cells += [""] * 4 if lost else [f"{1e3 * v + 20:.6f}" for v in position_m[k]] + ["1.0"]
        cells += ["12.5", "-800.25", "3001.0"] if k % 3 else ["", "", ""]
        lines.append(",".join(cells))
    path.write_text("\r\n".join(lines) + "\r\n")


def test_read_motive_csv_two_bodies_with_dropouts(tmp_path):
    time_s = np.arange(120) / 240
    pos_a, quat_a = swing(time_s)
    pos_b, quat_b = pos_a[::-1] + 0.5, quat_a[::-1]
    lost_b = np.zeros(120, bool)
    lost_b[40:60] = True
    path = tmp_path / "take.csv"
    write_motive_csv(path, time_s, {"PaddleRed": (pos_a, quat_a), "PaddleBlack": (pos_b, quat_b)},
                     {"PaddleRed": np.zeros(120, bool), "PaddleBlack": lost_b})
    bodies = read_motive_csv(path)
    assert sorted(bodies) == ["PaddleBlack", "PaddleRed"]
    red, black = bodies["PaddleRed"], bodies["PaddleBlack"]
    assert list(red.columns) == ["time_ns", "x", "y", "z", "qx", "qy", "qz", "qw"]
    assert red["time_ns"].dtype == np.int64
    np.testing.assert_array_equal(red["time_ns"], np.round(np.round(time_s, 6) * 1e9).astype(np.int64))
    np.testing.assert_allclose(red[["x", "y", "z"]], pos_a, atol=1e-9)  # mm with 6 decimals -> m
    np.testing.assert_allclose(red[["qx", "qy", "qz", "qw"]], quat_a, atol=1e-6)
    assert black[["x", "qw"]].iloc[40:60].isna().all().all()
    np.testing.assert_allclose(black[["x", "y", "z"]][~lost_b], pos_b[~lost_b], atol=1e-9)
    assert red.attrs["Take Name"] == "Rally 012" and red.attrs["Length Units"] == "Millimeters"

    target = np.arange(0, 50) * 10_000_000
    _, _, valid = resample_poses(black["time_ns"], black[["x", "y", "z"]], black[["qx", "qy", "qz", "qw"]],
                                 target)
    np.testing.assert_array_equal(valid, (target / 1e9 <= 39 / 240) | (target / 1e9 >= 60 / 240))


def test_a_motive_csv_export_gives_the_paddle_table_of_the_stream(tmp_path):
    # the same take as a Motive CSV (time from the take's start, mm, NaN rows where lost) and as the
    # OptiTrack MCAP stream (camera-clock ns, lost samples absent): the paddle stage's table is the same
    take_start_ns = 1_767_225_600_000_000_000 + 123_456_789
    time_s = np.round(np.arange(240) / 240, 6)
    pos, quat = swing(time_s)
    lost = np.zeros(240, bool)
    lost[100:130] = True
    write_motive_csv(tmp_path / "optitrack.csv", time_s, {"paddle_near": (pos, quat)}, {"paddle_near": lost})
    with OptitrackWriter(tmp_path / "optitrack.mcap") as writer:
        for k in np.flatnonzero(~lost):
            writer.add("paddle_near", take_start_ns + round(time_s[k] * 1e9), pos[k], quat[k])
    frames = take_start_ns + np.arange(0, 100) * 10_000_000  # the camera clock, 100 Hz
    T = make_transform(Rotation.from_euler("z", 0.3).as_matrix(), [0.1, -0.2, 0.05])
    tables = [paddle_table(read_optitrack_poses(tmp_path / f"optitrack.{ext}", take_start_ns=take_start_ns),
                           {"near": "paddle_near"}, T, frames) for ext in ("csv", "mcap")]
    np.testing.assert_array_equal(tables[0]["valid"], tables[1]["valid"])
    assert not tables[0]["valid"].all() and tables[0]["valid"].any()  # the dropout is a gap in both
    valid = tables[0]["valid"].to_numpy()
    numbers = tables[0].columns.drop(["time_ns", "player", "valid"])
    # the CSV holds quaternions to 6 decimals: rotation entries agree to a few 1e-6, positions to 1e-9 m
    np.testing.assert_allclose(tables[0][numbers][valid], tables[1][numbers][valid], atol=5e-6)
    with pytest.raises(ValueError, match="lab.motive_take_start_ns"):
        read_optitrack_poses(tmp_path / "optitrack.csv")
    with pytest.raises(ValueError, match=r"\.mcap.*\.csv"):
        read_optitrack_poses(tmp_path / "optitrack.txt")


def _fixture(tmp_path):
    path = tmp_path / "take.csv"
    time_s = np.arange(10) / 240
    pos, quat = swing(time_s)
    write_motive_csv(path, time_s, {"Paddle": (pos, quat)}, {"Paddle": np.zeros(10, bool)})
    return path, path.read_bytes().decode().split("\r\n")


def test_read_motive_csv_names_file_and_line_of_a_bad_cell(tmp_path):
    path, lines = _fixture(tmp_path)
    lines[10] = lines[10].replace(lines[10].split(",")[4], "n/a", 1)
    path.write_text("\r\n".join(lines))
    with pytest.raises(ValueError, match=r"take\.csv: line 11: not a number"):
        read_motive_csv(path)


def test_read_motive_csv_names_a_truncated_line(tmp_path):
    path, lines = _fixture(tmp_path)
    lines[-2] = lines[-2][:30]
    path.write_text("\r\n".join(lines))
    with pytest.raises(ValueError, match=r"take\.csv: line 17 has 5 cells, the header has 17"):
        read_motive_csv(path)


@pytest.mark.parametrize(("old", "new", "message"), [
    ("Length Units,Millimeters", "Length Units,Furlongs", "'Length Units' must be one of"),
    ("Rotation Type,Quaternion", "Rotation Type,XYZ", "need 'Rotation Type,Quaternion'"),
    ("Format Version", "Frame Version", "not a Motive CSV export"),
    (",Type,", ",Kind,", "missing the 'Type' header line"),
    ("Time (Seconds)", "Time", "must be 'Time \\(Seconds\\)'"),
])
def test_read_motive_csv_rejects_a_bad_header(tmp_path, old, new, message):
    path, lines = _fixture(tmp_path)
    path.write_text("\r\n".join(lines).replace(old, new, 1))
    with pytest.raises(ValueError, match=message):
        read_motive_csv(path)


def test_read_motive_csv_names_a_body_missing_a_column(tmp_path):
    path, lines = _fixture(tmp_path)
    comp = lines[5].split(",")
    comp[comp.index("Position")] = "Velocity"
    lines[5] = ",".join(comp)
    path.write_text("\r\n".join(lines))
    with pytest.raises(ValueError, match=r"rigid body 'Paddle' lacks the columns \['x'\]"):
        read_motive_csv(path)


def test_a_gap_of_max_gap_s_on_a_nanosecond_or_a_microsecond_clock_is_bridged():
    """12 ticks of 240 Hz is 50 ms: 50.000004 ms with ticks rounded to the ns, 50.000 ms in a Motive CSV
    (times to the us). Both are bridged at max_gap_s = 0.05; a gap 2 us longer is not."""
    quats = np.tile([0.0, 0.0, 0.0, 1.0], (2, 1))
    positions = np.zeros((2, 3))
    for gap_ns, bridged in ((50_000_004, True), (50_000_000, True), (50_002_000, False)):
        _, _, valid = resample_poses(np.array([0, gap_ns]), positions, quats, np.array([25_000_000]),
                                     max_gap_s=0.05)
        assert valid[0] == bridged, gap_ns
