"""The twin's rig and renderer: geometry of the rig, the ball's truth, occlusion, calibration images."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pingpong.common.camera import UNDISTORT_CRITERIA
from pingpong.common.patterns import CHECKERBOARD, TABLE_CHARUCO, table_pattern_object_points
from pingpong.twin import render
from pingpong.twin.calibration_images import checkerboard_poses, render_checkerboard_view, render_table_view
from pingpong.twin.rig import lens_distortion, make_rig

# the detector thresholds documented in render.py (OpenCV HSV)
BALL_LO, BALL_HI = (6, 150, 110), (19, 255, 255)

# a standing BODY_25 skeleton, feet at the origin, facing -y (m)
STANDING = np.array([
    (0, -0.08, 1.62), (0, 0, 1.45), (-0.19, 0, 1.43), (-0.24, -0.15, 1.20), (-0.20, -0.35, 1.05),
    (0.19, 0, 1.43), (0.26, -0.05, 1.15), (0.28, -0.08, 0.90), (0, 0, 0.95), (-0.1, 0, 0.95),
    (-0.12, -0.05, 0.52), (-0.13, 0, 0.08), (0.1, 0, 0.95), (0.12, -0.05, 0.52), (0.13, 0, 0.08),
    (-0.035, -0.07, 1.66), (0.035, -0.07, 1.66), (-0.08, 0, 1.64), (0.08, 0, 1.64), (0.14, -0.18, 0.02),
    (0.18, -0.16, 0.02), (0.13, 0.04, 0.03), (-0.14, -0.18, 0.02), (-0.18, -0.16, 0.02), (-0.13, 0.04, 0.03)])


@pytest.fixture(scope="module")
def lab_scene():
    rng = np.random.default_rng(7)
    cameras = make_rig(rng)
    lab = render.make_lab(rng)
    backgrounds = [render.render_background(c, lab, rng) for c in cameras[:2]]  # two keep the test quick
    return cameras, lab, backgrounds


def largest_orange_blob_centre(image):
    mask = cv2.inRange(cv2.cvtColor(image, cv2.COLOR_BGR2HSV), BALL_LO, BALL_HI)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    blob = np.zeros_like(mask)
    cv2.drawContours(blob, [max(contours, key=cv2.contourArea)], -1, 255, -1)
    m = cv2.moments(blob & mask, binaryImage=True)
    return np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])


def test_every_point_above_the_table_is_seen_by_at_least_two_cameras():
    for seed in range(3):
        cameras = make_rig(np.random.default_rng(seed))
        grid = np.stack(np.meshgrid(np.linspace(-0.9, 0.9, 7), np.linspace(-1.6, 1.6, 9),
                                    np.linspace(0.0, 1.0, 5)), -1).reshape(-1, 3)
        seen = np.zeros(len(grid), int)
        for cam in cameras:
            px = cam.project(grid)
            seen += ((cam.depth(grid) > 0) & (px[:, 0] >= 0) & (px[:, 0] < cam.width)
                     & (px[:, 1] >= 0) & (px[:, 1] < cam.height))
        assert seen.min() >= 2


def test_focal_length_scales_with_resolution():
    small = make_rig(np.random.default_rng(1), width=480, height=360)
    large = make_rig(np.random.default_rng(1), width=1440, height=1080)
    for a, b in zip(small, large, strict=True):
        assert b.K[0, 0] / a.K[0, 0] == pytest.approx(3.0, rel=1e-9)
        np.testing.assert_allclose(a.center, b.center)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_radial_distortion_is_monotonic_everywhere(seed):
    k1, k2 = lens_distortion(np.random.default_rng(seed))[:2]
    r = np.linspace(0, 5, 2001)
    assert (np.diff(r * (1 + k1 * r**2 + k2 * r**4)) > 0).all()


def test_sub_pixel_rays_are_exact_undistortion(lab_scene):
    cam, bg = lab_scene[0][1], lab_scene[2][1]
    rays = render.subpixel_rays(bg.ray_map, 3, 5, 20, 10, 4)
    xs = 3 + (np.arange(80) + 0.5) / 4 - 0.5
    ys = 5 + (np.arange(40) + 0.5) / 4 - 0.5
    grid = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 1, 2)
    exact = cv2.undistortPoints(grid, cam.K, cam.dist, None, None, None, UNDISTORT_CRITERIA)
    assert np.abs(rays - exact.reshape(40, 80, 2)).max() * cam.K[0, 0] < 0.01  # px


def test_ball_centre_matches_projection_without_blur(lab_scene):
    cameras, _, backgrounds = lab_scene
    rng = np.random.default_rng(3)
    errors = []
    for i in range(40):
        cam, bg = cameras[i % 2], backgrounds[i % 2]
        ball = np.array([rng.uniform(-0.7, 0.7), rng.uniform(-1.3, 1.3), rng.uniform(0.05, 0.8)])
        image, truth = render.render_frame(bg, cam, ball[None], [], [], rng)
        assert truth.visibility == pytest.approx(1.0, abs=1e-6)
        np.testing.assert_allclose(truth.pixel, cam.project(ball)[0])
        errors.append(np.linalg.norm(largest_orange_blob_centre(image) - truth.pixel))
    assert max(errors) < 0.5, errors


def test_motion_blur_keeps_the_streak_centred_and_after_jpeg_the_ball_is_found(lab_scene):
    cameras, _, backgrounds = lab_scene
    rng = np.random.default_rng(4)
    errors = []
    for i in range(40):
        cam, bg = cameras[i % 2], backgrounds[i % 2]
        centre = np.array([rng.uniform(-0.7, 0.7), rng.uniform(-1.3, 1.3), rng.uniform(0.05, 0.8)])
        velocity = rng.normal(0, 6, 3)  # m/s over a 2 ms exposure
        positions = centre + np.linspace(-0.001, 0.001, 7)[:, None] * velocity
        image, truth = render.render_frame(bg, cam, positions, [], [], rng)
        decoded = cv2.imdecode(np.frombuffer(render.encode_jpeg(image, 90), np.uint8), cv2.IMREAD_COLOR)
        found = largest_orange_blob_centre(decoded)
        assert found is not None
        errors.append(np.linalg.norm(found - truth.pixel))
    assert np.median(errors) < 0.5 and max(errors) < 1.5, errors


def test_the_empty_lab_has_no_ball_coloured_blob(lab_scene):
    cameras, lab, backgrounds = lab_scene
    rng = np.random.default_rng(5)
    for cam, bg in zip(cameras[:2], backgrounds, strict=True):
        with_bucket = render.render_background(cam, lab, rng, intermittent=True, ray_map=bg.ray_map)
        for background in (bg, with_bucket):
            image, _ = render.render_frame(background, cam, None, [], [], rng)
            decoded = cv2.imdecode(np.frombuffer(render.encode_jpeg(image), np.uint8), cv2.IMREAD_COLOR)
            mask = cv2.inRange(cv2.cvtColor(decoded, cv2.COLOR_BGR2HSV), BALL_LO, BALL_HI)
            n, _, stats, _ = cv2.connectedComponentsWithStats(mask)
            assert n == 1 or stats[1:, cv2.CC_STAT_AREA].max() <= 2


def test_a_paddle_or_player_in_front_hides_the_ball(lab_scene):
    cameras, _, backgrounds = lab_scene
    cam, bg = cameras[0], backgrounds[0]
    rng = np.random.default_rng(6)
    ball = np.array([0.1, -0.3, 0.4])
    towards_camera = (cam.center - ball) / np.linalg.norm(cam.center - ball)
    # a paddle 30 cm in front of the ball, its face to the camera
    z = towards_camera
    x = np.cross([0, 0, 1.0], z)
    x /= np.linalg.norm(x)
    paddle = (ball + 0.3 * towards_camera, np.column_stack([x, np.cross(z, x), z]))
    _, truth = render.render_frame(bg, cam, ball[None], [], [paddle], rng)
    assert truth.visibility == 0.0
    # the same paddle behind the ball does not
    _, truth = render.render_frame(bg, cam, ball[None], [], [(ball - 0.3 * towards_camera, paddle[1])], rng)
    assert truth.visibility == pytest.approx(1.0)
    # a player whose chest is on the line of sight
    chest = ball + 1.0 * towards_camera
    player = STANDING + (chest - STANDING[[1, 8]].mean(axis=0))
    _, truth = render.render_frame(bg, cam, ball[None], [player], [], rng)
    assert truth.visibility == 0.0


def test_table_top_and_image_border_hide_the_ball(lab_scene):
    cameras, _, backgrounds = lab_scene
    rng = np.random.default_rng(8)
    cam, bg = cameras[0], backgrounds[0]
    _, truth = render.render_frame(bg, cam, np.array([[0.0, 0.0, -0.3]]), [], [], rng)  # under the table
    assert truth.visibility == 0.0
    outside = cam.center + 0.5 * (cam.R.T @ np.array([-0.7, 0.0, 1.0]))  # far left of the field of view
    _, truth = render.render_frame(bg, cam, outside[None], [], [], rng)
    assert truth.visibility == 0.0


def test_opencv_calibration_on_the_rendered_images_recovers_the_camera(lab_scene):
    cameras, lab, backgrounds = lab_scene
    cam, bg = cameras[1], backgrounds[1]
    rng = np.random.default_rng(9)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
    object_points, image_points = [], []
    for R, t in checkerboard_poses(cam, 12, rng):
        gray = cv2.cvtColor(render_checkerboard_view(cam, bg, R, t, rng), cv2.COLOR_BGR2GRAY)
        found, corners = cv2.findChessboardCorners(gray, CHECKERBOARD.pattern_size)
        if found:
            object_points.append(CHECKERBOARD.object_points().astype(np.float32))
            image_points.append(cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), criteria))
    assert len(object_points) >= 10
    rms, K, dist, _, _ = cv2.calibrateCamera(object_points, image_points, (cam.width, cam.height), None, None)
    assert rms < 0.5
    assert K[0, 0] == pytest.approx(cam.K[0, 0], rel=0.005)
    assert np.abs(K[:2, 2] - cam.K[:2, 2]).max() < 2.0

    image = render_table_view(cam, lab, rng, ray_map=bg.ray_map)
    corners, ids, _, _ = cv2.aruco.CharucoDetector(TABLE_CHARUCO.board()).detectBoard(image)
    assert ids is not None and len(ids) >= 12
    corners = cv2.cornerSubPix(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), corners, (2, 2), (-1, -1), criteria)
    objects = table_pattern_object_points(ids)
    np.testing.assert_allclose(corners.reshape(-1, 2), cam.project(objects), atol=0.5)
    for K_used, dist_used in ((cam.K, cam.dist), (K, dist)):
        ok, rvec, tvec = cv2.solvePnP(objects, corners, K_used, dist_used)
        R = cv2.Rodrigues(rvec)[0]
        assert ok and np.linalg.norm(-R.T @ tvec.ravel() - cam.center) < 0.01


def test_both_backgrounds_at_once_are_those_of_two_calls():
    """render_backgrounds casts the distractor's bands alone a second time: the same bits, the same draws."""
    rng = np.random.default_rng(11)
    cameras = make_rig(rng, 4, 320, 240)
    lab = render.make_lab(rng)
    seen = 0
    for cam in cameras:
        one, two = np.random.default_rng(3), np.random.default_rng(3)
        together = render.render_backgrounds(cam, lab, one)
        apart = [render.render_background(cam, lab, two, intermittent=b) for b in (False, True)]
        for a, b in zip(together, apart, strict=True):
            assert a.table_box == b.table_box
            for name in ("image", "ray_map", "table_depth", "noise_up", "noise_down"):
                assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert one.integers(1 << 62) == two.integers(1 << 62)
        seen += (together[0].image != together[1].image).any()
    assert seen > 0  # some camera sees the distractor: its bands were cast again, the others reused
