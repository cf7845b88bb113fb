"""What each camera of the twin sees: the empty lab once, then the moving things per frame.

Distortion is rendered exactly by inverse mapping: every output (sub)pixel is undistorted to its
ray (cv2.undistortPoints, iterated to 1e-12) and the ray is intersected with the scene, so the image
agrees with `Camera.project` to numerical precision. The empty lab (room, table, net, distractors)
is ray cast once per camera with 2x2 supersampling. Per frame only players (limb capsules drawn with
cv2, depth sorted with the ball), paddles and the ball (ray-sphere tests at 4x4 subsamples per
pixel and at K sub-exposure positions, averaged: motion blur) are drawn, in small regions over a
copy of the cached image; then sensor noise. Balls at rest (twin.room's) are drawn into the cached image
once (with_still_balls) and again only in a frame where something overlaps them.

Colours (OpenCV HSV: H in [0, 180), S and V in [0, 255]) are chosen so that an orange-ball detector
has a principled threshold, roughly H in [6, 19], S >= 150, V >= 110:
  ball           H 12, S 235, V 150..245 (diffuse shading: 0.62 + 0.38 max(0, n.l) of V 245)
  poster         H 14, S  90, V 215   faded orange print on a wall: rejected by S
  cardboard box  H 14, S 170, V  70   dark brown-orange: rejected by V
  extinguisher   H  1, S 220, V 175   red: rejected by H (low side)
  ball bucket    H 24, S 230, V 225   yellow-orange, present only sometimes: rejected by H (high side)
  skin           H 8-11, S 95-140, V 140-225: rejected by S
  paddle handle  H 15, S 100, V 160: rejected by S; red rubber H 0, S 210, V 165: rejected by H
  backdrop       H 75 (blue-green, so anti-aliased red-on-backdrop edges stay dull instead of
                 turning orange), table top H 95, barriers H 115, floor grey.
With config twin.room (pingpong.twin.room, off by default) a club room adds look-alikes inside or at the
edge of that window: wooden boxes H 13, S 178, V 112 (sides) / 150 (top); a banner's ball-orange dots
H 12, S 220, V 220; the bystander's orange shirt H 14, S 185, V 175; balls of the ball's own colour (held,
on the floor: render_scene draws any number); and a gain on every value per frame (drift, flicker).
Anti-aliased edges and JPEG blend these with their surroundings: isolated 1-2 px blobs can pass
the thresholds at red/skin edges, so take the largest blob. The ball is 3-4 px across at 480x360;
write JPEG with full-resolution chroma (encode_jpeg's default "444"), since 4:2:0 leaves only
1-3 of its pixels saturated. Measured on the twin (thresholds above, largest blob, JPEG q90
4:4:4, 480x360): median centre error 0.18 px, p95 0.35 px, no misses on visible balls.
"""

from collections.abc import Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np
from scipy.ndimage import map_coordinates
from scipy.special import ndtri  # the normal quantile; scipy.stats would add 0.4 s to every camera job

from pingpong.common.camera import UNDISTORT_CRITERIA, Camera
from pingpong.common.patterns import TableCharuco
from pingpong.frames import BALL_RADIUS, NET_HEIGHT, NET_OVERHANG, TABLE_HALF_LENGTH, TABLE_HALF_WIDTH
from pingpong.twin.rig import FLOOR_Z


def hsv_to_bgr(h: float, s: float, v: float) -> np.ndarray:
    """BGR (3,) float of an OpenCV-range HSV colour."""
    return cv2.cvtColor(np.uint8([[[h, s, v]]]), cv2.COLOR_HSV2BGR)[0, 0].astype(np.float32)


BALL_HSV = (12, 235, 245)
BALL_AMBIENT, BALL_DIFFUSE = 0.62, 0.38
LIGHT_DIR = np.array([0.2, 0.3, 1.0]) / np.linalg.norm([0.2, 0.3, 1.0])  # ceiling lights, world frame
NET_TRANSMISSION = 0.45  # fraction of light through the net mesh
NET_TAPE = 0.015  # white band along the net's top, m
LINE_WIDTH = 0.02  # table edge lines, m; the centre line is 3 mm
ROOM = np.array([[-6.0, -8.0, FLOOR_Z], [6.0, 8.0, 3.0]])  # walls, floor and ceiling, table frame, m


# ----------------------------------------------------------------------------------------- rays

def pixel_ray_map(camera: Camera) -> np.ndarray:
    """Normalised undistorted coordinates (H+2, W+2, 2) of pixel centres x, y in -1..W, -1..H."""
    xs, ys = np.meshgrid(np.arange(-1.0, camera.width + 1), np.arange(-1.0, camera.height + 1))
    px = np.stack([xs.ravel(), ys.ravel()], axis=1).reshape(-1, 1, 2)
    rays = cv2.undistortPoints(px, camera.K, camera.dist, None, None, None, UNDISTORT_CRITERIA)
    return rays.reshape(camera.height + 2, camera.width + 2, 2)


def subpixel_rays(ray_map: np.ndarray, x0: int, y0: int, w: int, h: int, ss: int) -> np.ndarray:
    """Normalised coordinates (h*ss, w*ss, 2) of ss x ss subsample centres of pixels [x0, x0+w) x [y0, y0+h).

    Bilinear between exact pixel-centre rays (the map's curvature makes that exact to ~1e-3 px);
    outside the image it extrapolates linearly from the border.
    """
    height, width = ray_map.shape[0] - 2, ray_map.shape[1] - 2
    if x0 >= 0 and y0 >= 0 and x0 + w <= width and y0 + h <= height:
        # inside: cv2.resize samples exactly these subsample centres (float weights for float input)
        block = np.ascontiguousarray(ray_map[y0:y0 + h + 2, x0:x0 + w + 2])
        fine = cv2.resize(block, ((w + 2) * ss, (h + 2) * ss), interpolation=cv2.INTER_LINEAR)
        return fine[ss:-ss, ss:-ss]
    xs = x0 + (np.arange(w * ss) + 0.5) / ss - 0.5
    ys = y0 + (np.arange(h * ss) + 0.5) / ss - 0.5
    ix = np.clip(np.floor(xs), -1, width - 1).astype(int)
    iy = np.clip(np.floor(ys), -1, height - 1).astype(int)
    fx = (xs - ix)[None, :, None]
    fy = (ys - iy)[:, None, None]
    r0, c0 = iy[:, None] + 1, ix[None, :] + 1
    top = ray_map[r0, c0] * (1 - fx) + ray_map[r0, c0 + 1] * fx
    bottom = ray_map[r0 + 1, c0] * (1 - fx) + ray_map[r0 + 1, c0 + 1] * fx
    return top * (1 - fy) + bottom * fy


def world_rays(camera: Camera, normalised: np.ndarray) -> np.ndarray:
    """World-frame directions (..., 3) of normalised coordinates (..., 2); camera depth = ray parameter."""
    d = np.concatenate([normalised, np.ones(normalised.shape[:-1] + (1,))], axis=-1)
    return d @ camera.R  # R^T d for each d


def average_subsamples(values: np.ndarray, ss: int) -> np.ndarray:
    """Box-filter (h*ss, w*ss, C) subsamples down to (h, w, C) pixels."""
    hs, ws, c = values.shape
    return values.reshape(hs // ss, ss, ws // ss, ss, c).mean(axis=(1, 3))


# ------------------------------------------------------------------------------------------ lab

@dataclass(frozen=True)
class Box:
    lo: tuple[float, float, float]  # table frame, m
    hi: tuple[float, float, float]
    hsv: tuple[float, float, float]


@dataclass(frozen=True)
class Cylinder:
    """A vertical cylinder standing on z0."""

    x: float
    y: float
    radius: float
    z0: float
    z1: float
    hsv: tuple[float, float, float]


@dataclass(frozen=True)
class Poster:
    """A print on the wall y = wall_y (the far wall as seen from the other end)."""

    wall_y: float
    lo: tuple[float, float]  # (x, z) of the lower left corner, m
    hi: tuple[float, float]  # and of the upper right
    hsv: tuple[float, float, float]
    marks: tuple[tuple[float, float, float], ...] = ()  # printed dots (x, z, radius), m (twin.room's sign)
    mark_hsv: tuple[float, float, float] = (0, 0, 0)


@dataclass(frozen=True)
class Lab:
    """The static room: one layout shared by all cameras. `intermittent` is drawn only when asked."""

    boxes: tuple[Box, ...]
    cylinders: tuple[Cylinder, ...]
    posters: tuple[Poster, ...]
    intermittent: Cylinder


POSTER_HSV = (14, 90, 215)
CARDBOARD_HSV = (14, 170, 70)
EXTINGUISHER_HSV = (1, 220, 175)
BUCKET_HSV = (24, 230, 225)
TABLE_TOP_HSV = (95, 190, 80)
LINE_HSV = (0, 0, 235)
NET_HSV = (115, 150, 60)
FLOOR_HSV = (110, 15, 125)
WALL_HSV = (75, 150, 120)  # blue-green: its blends with red stay dull, not orange
CEILING_HSV = (0, 0, 200)
BARRIER_HSV = (115, 200, 90)
LEG_HSV = (0, 0, 45)


TABLE_SLAB = ((-TABLE_HALF_WIDTH, -TABLE_HALF_LENGTH, -0.025), (TABLE_HALF_WIDTH, TABLE_HALF_LENGTH, 0.0))
TABLE_LEGS = tuple(Box((-0.62, y - 0.025, FLOOR_Z), (0.62, y + 0.025, -0.08), LEG_HSV) for y in (-0.95, 0.95))


def make_lab(rng: np.random.Generator) -> Lab:
    """A room with the table, court barriers and distractors at random places behind both ends."""
    z_floor = FLOOR_Z
    barriers = []
    for sign in (-1, 1):  # 0.7 m high court surrounds behind each end and along the sides
        barriers.append(Box((-3.2, sign * 5.5 - 0.02, z_floor), (3.2, sign * 5.5 + 0.02, z_floor + 0.7),
                            BARRIER_HSV))
        barriers.append(Box((sign * 3.2 - 0.02, -5.5, z_floor), (sign * 3.2 + 0.02, 5.5, z_floor + 0.7),
                            BARRIER_HSV))
    posts = [Box((s * (TABLE_HALF_WIDTH + NET_OVERHANG) - 0.015, -0.015, 0.0),
                 (s * (TABLE_HALF_WIDTH + NET_OVERHANG) + 0.015, 0.015, NET_HEIGHT), LEG_HSV)
             for s in (-1, 1)]
    boxes, cylinders, posters = [], [], []
    for sign in (-1, 1):
        x = rng.uniform(-1.8, 1.8)
        posters.append(Poster(sign * ROOM[1, 1], (x - 0.4, rng.uniform(0.6, 1.0)),
                              (x + 0.4, rng.uniform(1.6, 2.0)), POSTER_HSV))
        bx, by = rng.uniform(1.0, 2.6) * rng.choice([-1, 1]), sign * rng.uniform(6.0, 7.5)
        boxes.append(Box((bx - 0.3, by - 0.25, z_floor), (bx + 0.3, by + 0.25, z_floor + 0.45),
                         CARDBOARD_HSV))
        cylinders.append(Cylinder(rng.uniform(-2.5, 2.5), sign * (ROOM[1, 1] - 0.12), 0.08, z_floor + 1.0,
                                  z_floor + 1.55, EXTINGUISHER_HSV))
    bucket = Cylinder(rng.uniform(-2.5, 2.5), rng.choice([-1, 1]) * rng.uniform(4.0, 5.2), 0.16, z_floor,
                      z_floor + 0.35, BUCKET_HSV)
    return Lab(tuple(barriers + list(TABLE_LEGS) + posts + boxes), tuple(cylinders), tuple(posters), bucket)


def _hit_box(o, d, lo, hi):
    """Entry distance (N,) of rays o + s d into an axis-aligned box (inf: miss) and the entry axis (N,)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (np.asarray(lo) - o) / d
        t1 = (np.asarray(hi) - o) / d
    near = np.minimum(t0, t1)
    far = np.maximum(t0, t1)
    near = np.where(np.isnan(near), -np.inf, near)
    far = np.where(np.isnan(far), np.inf, far)
    entry = near.max(axis=1)
    hit = (entry <= far.min(axis=1)) & (entry > 0)
    return np.where(hit, entry, np.inf), near.argmax(axis=1)


def _hit_cylinder(o, d, cyl: Cylinder):
    """Distance (N,) to a vertical cylinder's side or top (inf: miss) and whether it was the top."""
    dx, dy = d[:, 0], d[:, 1]
    ox, oy = o[0] - cyl.x, o[1] - cyl.y
    a = dx**2 + dy**2
    b = ox * dx + oy * dy
    disc = b**2 - a * (ox**2 + oy**2 - cyl.radius**2)
    with np.errstate(invalid="ignore", divide="ignore"):
        s_side = (-b - np.sqrt(disc)) / a
        z_side = o[2] + s_side * d[:, 2]
        side = np.where((disc >= 0) & (s_side > 0) & (z_side >= cyl.z0) & (z_side <= cyl.z1), s_side, np.inf)
        s_top = (cyl.z1 - o[2]) / d[:, 2]
    px, py = o[0] + s_top * dx - cyl.x, o[1] + s_top * dy - cyl.y
    top = np.where((s_top > 0) & (px**2 + py**2 <= cyl.radius**2), s_top, np.inf)
    return np.minimum(side, top), top < side


def _room_colour(o, d, lab: Lab):
    """Distance and colour where rays leave the room through a wall, the floor or the ceiling."""
    with np.errstate(divide="ignore"):
        bound = np.where(d > 0, ROOM[1], ROOM[0])
        s_axes = (bound - o) / d
    s_axes = np.where(np.isfinite(s_axes) & (s_axes > 0), s_axes, np.inf)
    axis = s_axes.argmin(axis=1)
    s = s_axes[np.arange(len(d)), axis]
    p = o + s[:, None] * d
    colour = np.empty((len(d), 3), np.float32)
    floor = (axis == 2) & (d[:, 2] < 0)
    ceiling = (axis == 2) & (d[:, 2] >= 0)
    colour[:] = hsv_to_bgr(*WALL_HSV) * (0.8 + 0.2 * np.clip((p[:, 2] - FLOOR_Z) / 3.0, 0, 1))[:, None]
    seams = (np.abs(p[:, 0] - np.round(p[:, 0])) < 0.005) | (np.abs(p[:, 1] - np.round(p[:, 1])) < 0.005)
    colour[floor] = hsv_to_bgr(*FLOOR_HSV) * np.where(seams[floor], 0.85, 1.0)[:, None]
    colour[ceiling] = hsv_to_bgr(*CEILING_HSV)
    for poster in lab.posters:
        (x0, z0), (x1, z1) = poster.lo, poster.hi
        on = ((axis == 1) & (np.abs(p[:, 1] - poster.wall_y) < 1e-6) & (p[:, 0] >= x0) & (p[:, 0] <= x1)
              & (p[:, 2] >= z0) & (p[:, 2] <= z1))
        colour[on] = hsv_to_bgr(*poster.hsv)
        for x, z, radius in poster.marks:
            colour[on & ((p[:, 0] - x) ** 2 + (p[:, 2] - z) ** 2 <= radius**2)] = hsv_to_bgr(*poster.mark_hsv)
    return s, colour


def _table_top_colour(p, pattern: TableCharuco | None, texture: np.ndarray | None):
    """Colour (N, 3) of points p (N, 3) on the table top: the blue-green top, white lines, or the mat."""
    x, y = p[:, 0], p[:, 1]
    lines = ((np.abs(x) > TABLE_HALF_WIDTH - LINE_WIDTH) | (np.abs(y) > TABLE_HALF_LENGTH - LINE_WIDTH)
             | (np.abs(x) < 0.0015))
    colour = np.where(lines[:, None], hsv_to_bgr(*LINE_HSV), hsv_to_bgr(*TABLE_TOP_HSV))
    if pattern is not None:
        width, length = pattern.size
        bx = x - (pattern.center_x - width / 2)
        by = (pattern.center_y + length / 2) - y
        on = (bx >= 0) & (bx <= width) & (by >= 0) & (by <= length)
        texels_per_m = texture.shape[1] / width
        # texture pixel centres sit at (i + 0.5) / texels_per_m (generateImage's convention)
        grey = map_coordinates(texture, [by[on] * texels_per_m - 0.5, bx[on] * texels_per_m - 0.5], order=1,
                               mode="nearest")
        colour[on] = (25 + grey[:, None] * (215 / 255)).astype(np.float32)  # ink 25, paper 240
    return colour


def _in_view(camera: Camera, normalised: np.ndarray, lo, hi) -> np.ndarray:
    """Indices of rays (normalised coordinates (N, 2)) that can hit the box [lo, hi].

    A box in front of the camera projects inside the bounding rectangle of its corners, so the
    exact intersection tests run only on those rays.
    """
    corners = np.array(np.meshgrid(*zip(lo, hi, strict=True))).reshape(3, -1).T
    cam = corners @ camera.R.T + camera.t
    if (cam[:, 2] <= 1e-3).any():
        return np.arange(len(normalised))
    proj = cam[:, :2] / cam[:, 2:]
    lo_xy, hi_xy = proj.min(axis=0) - 1e-3, proj.max(axis=0) + 1e-3
    inside = ((normalised[:, 0] >= lo_xy[0]) & (normalised[:, 0] <= hi_xy[0])
              & (normalised[:, 1] >= lo_xy[1]) & (normalised[:, 1] <= hi_xy[1]))
    return np.flatnonzero(inside)


def _cylinder_box(cyl: Cylinder) -> tuple[tuple, tuple]:
    """Corners (lo, hi) of a cylinder's bounding box, for _in_view."""
    return (cyl.x - cyl.radius, cyl.y - cyl.radius, cyl.z0), (cyl.x + cyl.radius, cyl.y + cyl.radius, cyl.z1)


def _cast(camera: Camera, normalised: np.ndarray, lab: Lab, intermittent: bool, net: bool,
          pattern: TableCharuco | None, texture: np.ndarray | None) -> np.ndarray:
    """Colour (N, 3) of the empty lab along the rays of normalised coordinates (N, 2)."""
    o = camera.center
    d = world_rays(camera, normalised)
    s_best, colour = _room_colour(o, d, lab)

    def paint(idx, s, rgb):
        closer = s < s_best[idx]
        colour[idx[closer]] = rgb[closer]
        s_best[idx[closer]] = s[closer]

    for box in lab.boxes:
        idx = _in_view(camera, normalised, box.lo, box.hi)
        s, axis = _hit_box(o, d[idx], box.lo, box.hi)
        paint(idx, s, hsv_to_bgr(*box.hsv)[None, :] * np.where(axis == 2, 1.0, 0.75)[:, None])
    for cyl in lab.cylinders + ((lab.intermittent,) if intermittent else ()):
        idx = _in_view(camera, normalised, *_cylinder_box(cyl))
        s, top = _hit_cylinder(o, d[idx], cyl)
        paint(idx, s, hsv_to_bgr(*cyl.hsv)[None, :] * np.where(top, 1.0, 0.8)[:, None])
    lo, hi = TABLE_SLAB
    idx = _in_view(camera, normalised, lo, hi)
    s_table, axis = _hit_box(o, d[idx], lo, hi)
    table_colour = np.tile(hsv_to_bgr(*TABLE_TOP_HSV) * 0.6, (len(idx), 1))  # the top's edge faces
    top = np.isfinite(s_table) & (axis == 2)
    table_colour[top] = _table_top_colour(o + s_table[top, None] * d[idx[top]], pattern, texture)
    paint(idx, s_table, table_colour)
    if net:  # a see-through mesh with an opaque white tape on top
        reach = TABLE_HALF_WIDTH + NET_OVERHANG
        idx = _in_view(camera, normalised, (-reach, -1e-3, 0.0), (reach, 1e-3, NET_HEIGHT))
        with np.errstate(divide="ignore"):
            s_net = -o[1] / d[idx, 1]
        p = o + s_net[:, None] * d[idx]
        on = (s_net > 0) & (s_net < s_best[idx]) & (np.abs(p[:, 0]) <= reach) & (p[:, 2] >= 0) \
            & (p[:, 2] <= NET_HEIGHT)
        tape = idx[on & (p[:, 2] >= NET_HEIGHT - NET_TAPE)]
        colour[idx[on]] = NET_TRANSMISSION * colour[idx[on]] + (1 - NET_TRANSMISSION) * hsv_to_bgr(*NET_HSV)
        colour[tape] = hsv_to_bgr(*LINE_HSV)
    return colour


@dataclass(frozen=True)
class Background:
    """The empty lab as one camera sees it, with what the per-frame renderer reuses."""

    image: np.ndarray  # (H, W, 3) uint8 BGR
    ray_map: np.ndarray  # (H+2, W+2, 2) normalised coordinates of pixel centres, see pixel_ray_map
    table_depth: np.ndarray  # (H, W) camera depth of the table (top, edges, legs) per pixel, inf elsewhere
    table_box: tuple[int, int, int, int, float]  # x0, y0, x1, y1 (exclusive) of the table's pixels, min depth
    noise_up: np.ndarray  # (2 H W 3,) uint8 positive parts of a bank of sensor noise, see add_sensor_noise
    noise_down: np.ndarray  # (2 H W 3,) uint8 negative parts
    still_balls: "StillBalls | None" = None  # balls that never move, drawn once (with_still_balls)


def _table_depth(camera: Camera, ray_map: np.ndarray) -> np.ndarray:
    normalised = ray_map[1:-1, 1:-1].reshape(-1, 2)
    d = world_rays(camera, normalised)
    depth = _hit_box(camera.center, d, *TABLE_SLAB)[0]
    for leg in TABLE_LEGS:
        depth = np.minimum(depth, _hit_box(camera.center, d, leg.lo, leg.hi)[0])
    return depth.reshape(camera.height, camera.width).astype(np.float32)


BAND_ROWS = 64  # pixel rows ray cast at once: bounds the memory at high resolution


def _lab_image(camera: Camera, lab: Lab, ray_map: np.ndarray, *, intermittent: bool, net: bool,
               table_pattern: TableCharuco | None, ss: int, without: np.ndarray | None = None) -> np.ndarray:
    """The empty lab (H, W, 3) uint8, ray cast band by band with ss x ss subsamples per pixel.

    without: the same view without the distractor; with `intermittent`, the bands from which the
    distractor's box is out of view are taken from it (a band is cast on its own rays alone, so such a
    band is the same bit for bit) and only the others are cast.
    """
    h, w = camera.height, camera.width
    image = np.empty((h, w, 3), np.uint8)
    texture = None
    if table_pattern is not None:  # the printed mat at 160 texels per square, white 255, ink 0
        texture = table_pattern.board().generateImage(
            (table_pattern.squares_x * 160, table_pattern.squares_y * 160), marginSize=0,
            borderBits=1).astype(np.float32)
    for y0 in range(0, h, BAND_ROWS):
        rows = min(BAND_ROWS, h - y0)
        normalised = subpixel_rays(ray_map, 0, y0, w, rows, ss).reshape(-1, 2)
        if without is not None and intermittent \
                and not len(_in_view(camera, normalised, *_cylinder_box(lab.intermittent))):
            image[y0:y0 + rows] = without[y0:y0 + rows]
            continue
        colour = _cast(camera, normalised, lab, intermittent, net, table_pattern, texture)
        colour = colour.reshape(rows * ss, w * ss, 3).astype(np.float32)
        image[y0:y0 + rows] = np.clip(average_subsamples(colour, ss) + 0.5, 0, 255).astype(np.uint8)
    return image


def _background(image: np.ndarray, ray_map: np.ndarray, table_depth: np.ndarray, rng: np.random.Generator,
                noise_sigma: float) -> Background:
    """The Background of a lab image, with its bank of sensor noise drawn from rng."""
    noise_bytes = np.frombuffer(rng.bytes(2 * image.size), np.uint8)
    up, down = _noise_tables(noise_sigma)
    ys, xs = np.nonzero(np.isfinite(table_depth))
    table_box = (int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1,
                 float(table_depth[ys, xs].min())) if len(xs) else (0, 0, 0, 0, np.inf)
    return Background(image, ray_map, table_depth, table_box, cv2.LUT(noise_bytes, up).ravel(),
                      cv2.LUT(noise_bytes, down).ravel())


def render_background(camera: Camera, lab: Lab, rng: np.random.Generator, *, intermittent: bool = False,
                      net: bool = True, table_pattern: TableCharuco | None = None, ss: int = 2,
                      ray_map: np.ndarray | None = None, noise_sigma: float = 2.0) -> Background:
    """Ray cast the empty lab (ss x ss subsamples per pixel); `table_pattern` lays the ChArUco mat on the top.

    `intermittent` adds the sometimes-present distractor; `rng` draws the bank of sensor noise
    (std `noise_sigma`, DN) that frames rendered over this background get.
    """
    ray_map = pixel_ray_map(camera) if ray_map is None else ray_map
    image = _lab_image(camera, lab, ray_map, intermittent=intermittent, net=net, table_pattern=table_pattern,
                       ss=ss)
    return _background(image, ray_map, _table_depth(camera, ray_map), rng, noise_sigma)


def render_backgrounds(camera: Camera, lab: Lab, rng: np.random.Generator,
                       noise_sigma: float = 2.0) -> tuple[Background, Background]:
    """The lab without and with the distractor: what two calls of render_background give (the same
    bits and draws of rng), with one ray map and table depth, and only the bands in which the
    distractor can show cast twice (a camera that never sees it casts the lab once)."""
    ray_map = pixel_ray_map(camera)
    table_depth = _table_depth(camera, ray_map)
    plain = _lab_image(camera, lab, ray_map, intermittent=False, net=True, table_pattern=None, ss=2)
    with_distractor = _lab_image(camera, lab, ray_map, intermittent=True, net=True, table_pattern=None, ss=2,
                                 without=plain)
    return tuple(_background(image, ray_map, table_depth, rng, noise_sigma)  # in this order: rng's draws
                 for image in (plain, with_distractor))


# ---------------------------------------------------------------------------------- moving things

@dataclass(frozen=True)
class PlayerLook:
    """BGR colours of one person."""

    shirt: tuple
    shorts: tuple
    skin: tuple
    shoes: tuple


SHIRT_HSVS = ((110, 200, 150), (0, 0, 40), (0, 0, 225), (0, 0, 130), (65, 170, 120), (120, 180, 80))
SHORTS_HSVS = ((0, 0, 35), (115, 180, 70), (0, 0, 110))
SKIN_HSVS = ((10, 95, 225), (10, 115, 200), (9, 130, 170), (8, 140, 140))
SHOES_HSVS = ((0, 0, 230), (0, 0, 40))


def make_player_looks(rng: np.random.Generator, n: int) -> list[PlayerLook]:
    def pick(options):
        return tuple(float(c) for c in hsv_to_bgr(*options[rng.integers(len(options))]))
    return [PlayerLook(pick(SHIRT_HSVS), pick(SHORTS_HSVS), pick(SKIN_HSVS), pick(SHOES_HSVS))
            for _ in range(n)]


# (joint a, joint b, radius m, part): capsules between BODY_25 joints
LIMBS = (
    (1, 8, 0.13, "shirt"), (2, 5, 0.07, "shirt"), (2, 3, 0.05, "shirt"), (5, 6, 0.05, "shirt"),
    (3, 4, 0.038, "skin"), (6, 7, 0.038, "skin"), (1, 0, 0.055, "skin"), (9, 12, 0.09, "shorts"),
    (9, 10, 0.075, "shorts"), (12, 13, 0.075, "shorts"), (10, 11, 0.05, "skin"), (13, 14, 0.05, "skin"),
    (24, 22, 0.04, "shoes"), (21, 19, 0.04, "shoes"),
)
TORSO = [2, 5, 12, 9]  # RShoulder, LShoulder, LHip, RHip
HEAD_RADIUS = 0.11
HAND_RADIUS = 0.045
PADDLE_HALF_WIDTH, PADDLE_HALF_HEIGHT, HANDLE_LENGTH, HANDLE_RADIUS = 0.075, 0.079, 0.10, 0.015
RED_RUBBER = tuple(float(c) for c in hsv_to_bgr(0, 210, 165))
BLACK_RUBBER = tuple(float(c) for c in hsv_to_bgr(0, 0, 30))
HANDLE = tuple(float(c) for c in hsv_to_bgr(15, 100, 160))  # light wood
BALL_BGR = hsv_to_bgr(*BALL_HSV)
SHIFT = 4  # cv2 drawing fixed-point bits: 1/16 px
MIN_DEPTH = 0.1  # nearer than this (or behind the camera) is not drawn, m


@dataclass(slots=True)
class _Shape:
    """One depth-sorted 2D primitive: a capsule (thick segment), a disc or a polygon.

    Built in bulk per body or paddle (vectorised rounding and bounds), so the per-frame loop is only
    cv2 calls: Python overhead per shape, not drawing, was most of a frame's cost.
    """

    depth: float
    kind: str
    points: np.ndarray  # (n, 2) int32 pixels in cv2 fixed point (SHIFT fractional bits)
    size: int  # capsule thickness in pixels, disc radius in fixed point, 0 for polygons
    colour: tuple
    bbox: tuple[int, int, int, int]  # pixel bounds x0, y0, x1, y1 (exclusive upper)

    def draw(self, img: np.ndarray, colour, offset=(0, 0)) -> None:
        pts = self.points - (np.asarray(offset, np.int32) << SHIFT) if offset[0] or offset[1] else self.points
        if self.kind == "capsule":
            cv2.line(img, pts[0], pts[1], colour, self.size, cv2.LINE_AA, SHIFT)
        elif self.kind == "disc":
            cv2.circle(img, pts[0], self.size, colour, -1, cv2.LINE_AA, SHIFT)
        else:
            cv2.fillPoly(img, [pts], colour, cv2.LINE_AA, SHIFT)


def _fixed_point(px: np.ndarray) -> np.ndarray:
    return np.round(px * (1 << SHIFT)).astype(np.int32, order="C")  # cv2 wants contiguous points


def _bounds(px: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Pixel bounds [x0, y0, x1, y1] (n, m, 4) of shapes with points px (n, m, k, 2) and radii (n, m)."""
    lo = np.floor(px.min(axis=2) - radius[..., None] - 1)
    hi = np.ceil(px.max(axis=2) + radius[..., None] + 2)
    return np.concatenate([lo, hi], axis=2).astype(int)


def _append_shapes(frames: list[list[_Shape]], valid: np.ndarray, depth: np.ndarray, kind: str,
                   px: np.ndarray, radius: np.ndarray, size: np.ndarray, colours: list) -> None:
    """Append to each frame's list its valid shapes (n, m); colours per frame and shape (n, m)."""
    ii, jj = np.nonzero(valid)
    # the valid shapes' values picked out as arrays first, then as Python values: indexing nested lists
    # and arrays with numpy integers, shape by shape, cost more than building the shapes
    rows = zip(ii.tolist(), jj.tolist(), depth[ii, jj].tolist(), size[ii, jj].tolist(),
               _bounds(px, radius)[ii, jj].tolist(), _fixed_point(px)[ii, jj], strict=True)
    for i, j, z, thickness, bounds, points in rows:
        frames[i].append(_Shape(z, kind, points, thickness, colours[i][j], tuple(bounds)))


LIMB_ENDS = np.array([(a, b) for a, b, _, _ in LIMBS])
LIMB_RADII = np.array([r for _, _, r, _ in LIMBS])
HEAD_JOINTS = [0, 17, 18]
HANDS = ((3, 4), (6, 7))  # (elbow, wrist): the hand disc lies beyond the wrist


def _body_shapes(frames: list[list[_Shape]], camera: Camera, joints: np.ndarray, look: PlayerLook) -> None:
    """Append per frame the capsules, torso polygon, head and hand discs of BODY_25 skeletons (n, 25, 3)
    (NaN joints are not drawn)."""
    n, f = len(joints), camera.K[0, 0]
    ok = np.isfinite(joints).all(axis=2)
    head_seen = ok[:, HEAD_JOINTS]
    head = np.where(head_seen[..., None], joints[:, HEAD_JOINTS], 0.0).sum(axis=1) \
        / np.maximum(head_seen.sum(axis=1), 1)[:, None]
    hand_seen = np.stack([ok[:, e] & ok[:, w] for e, w in HANDS], axis=1)
    hands = np.stack([joints[:, w] + 0.4 * (joints[:, w] - joints[:, e]) for e, w in HANDS], axis=1)
    points = np.concatenate([joints, head[:, None], hands], axis=1)
    seen = np.concatenate([ok, head_seen.any(axis=1, keepdims=True), hand_seen], axis=1)
    points = np.where(seen[..., None], points, 0.0)
    depth = camera.depth(points.reshape(-1, 3)).reshape(n, -1)
    seen &= depth > MIN_DEPTH
    z = np.where(seen, depth, 1.0)
    px = camera.project(points.reshape(-1, 3)).reshape(n, -1, 2)

    limb_z = z[:, LIMB_ENDS].mean(axis=2)
    radius = f * LIMB_RADII / limb_z
    thickness = np.maximum(1, np.round(2 * radius)).astype(int)
    colours = [[getattr(look, part) for *_, part in LIMBS]] * n
    _append_shapes(frames, seen[:, LIMB_ENDS].all(axis=2), limb_z, "capsule", px[:, LIMB_ENDS], radius,
                   thickness, colours)
    torso_z = z[:, TORSO].mean(axis=1, keepdims=True)
    _append_shapes(frames, seen[:, TORSO].all(axis=1, keepdims=True), torso_z, "poly", px[:, None, TORSO],
                   np.zeros((n, 1)), np.zeros((n, 1), int), [[look.shirt]] * n)
    disc_radius = f * np.array([HEAD_RADIUS, HAND_RADIUS, HAND_RADIUS]) / z[:, 25:]
    _append_shapes(frames, seen[:, 25:], z[:, 25:], "disc", px[:, 25:, None], disc_radius,
                   np.round(disc_radius * (1 << SHIFT)).astype(int), [[look.skin] * 3] * n)


PADDLE_ANGLES = np.linspace(0, 2 * np.pi, 24, endpoint=False)
PADDLE_OUTLINE = np.vstack([  # paddle frame: blade rim (24 points), then the handle's two ends
    np.stack([PADDLE_HALF_WIDTH * np.cos(PADDLE_ANGLES), PADDLE_HALF_HEIGHT * np.sin(PADDLE_ANGLES),
              np.zeros_like(PADDLE_ANGLES)], axis=1),
    [[0, -PADDLE_HALF_HEIGHT, 0], [0, -PADDLE_HALF_HEIGHT - HANDLE_LENGTH, 0]]])


def _paddle_shapes(frames: list[list[_Shape]], camera: Camera, pos: np.ndarray, rot: np.ndarray) -> None:
    """Append per frame a paddle's blade (red or black side, whichever faces the camera) and handle;
    pos (n, 3), rot (n, 3, 3). Paddle frame: origin at the blade centre, x across the blade, y from the
    handle to the tip, z the normal out of the red side."""
    n = len(pos)
    known = np.isfinite(pos).all(axis=1) & np.isfinite(rot).all(axis=(1, 2))
    pos, rot = np.where(known[:, None], pos, 0.0), np.where(known[:, None, None], rot, np.eye(3))
    points = pos[:, None] + np.einsum("kj,nij->nki", PADDLE_OUTLINE, rot)
    depth = camera.depth(points.reshape(-1, 3)).reshape(n, -1)
    drawn = known & (depth > MIN_DEPTH).all(axis=1)
    depth = np.where(drawn[:, None], depth, 1.0)
    px = camera.project(points.reshape(-1, 3)).reshape(n, -1, 2)
    blade_z = depth[:, :24].mean(axis=1, keepdims=True)
    red = np.einsum("ni,ni->n", rot[:, :, 2], camera.center - pos) > 0
    _append_shapes(frames, drawn[:, None], blade_z, "poly", px[:, None, :24], np.zeros((n, 1)),
                   np.zeros((n, 1), int), [[RED_RUBBER if r else BLACK_RUBBER] for r in red])
    radius = camera.K[0, 0] * HANDLE_RADIUS / blade_z  # sized at the blade's depth
    _append_shapes(frames, drawn[:, None], depth[:, 24:].mean(axis=1, keepdims=True), "capsule",
                   px[:, None, 24:], radius, np.maximum(1, np.round(2 * radius)).astype(int), [[HANDLE]] * n)


def frame_shapes(camera: Camera, bodies: Sequence[np.ndarray], looks: Sequence[PlayerLook],
                 paddles: Sequence[tuple[np.ndarray, np.ndarray]]) -> list[list[_Shape]]:
    """Per frame, the depth-sorted (farthest first) shapes of people and paddles over n frames at once.

    bodies: BODY_25 joints (n, 25, 3) per person, table frame, NaN where not drawn; looks: one per
    person; paddles: (positions (n, 3), rotations (n, 3, 3)) per paddle. Vectorised over frames: per
    shape, Python and small-array overhead cost more than the drawing itself.
    """
    n = len(bodies[0]) if len(bodies) else len(paddles[0][0]) if len(paddles) else 0
    frames: list[list[_Shape]] = [[] for _ in range(n)]
    for joints, look in zip(bodies, looks, strict=False):
        _body_shapes(frames, camera, np.asarray(joints, float), look)
    for pos, rot in paddles:
        _paddle_shapes(frames, camera, np.asarray(pos, float), np.asarray(rot, float))
    for shapes in frames:
        shapes.sort(key=lambda shape: -shape.depth)
    return frames


@dataclass(frozen=True)
class BallTruth:
    """What a perfect detector would report for the ball in one frame."""

    pixel: np.ndarray  # (2,) distorted pixel of the mid-exposure centre (mean of the positions); NaN: no ball
    visibility: float  # visible fraction of the ball's (blurred) image: 0 when hidden or outside the image
    radius_px: float  # apparent radius at mid exposure


BALL_SS = 4  # subsamples per pixel side for the ball
OCCLUSION_MARGIN = 1e-3  # m: a ball farther than this beyond its radius from the table top's or the net's
# plane, on the camera's side, cannot be hidden by it (its front surface is nearer than the plane by mm,
# against rounding of ~1e-15 m), so its coverage is the bare hits, exactly what the full test gives


def _ball_layer(background: Background, camera: Camera, positions: np.ndarray):
    """The blurred ball as a layer, or None when it is behind the camera or wholly outside the image.

    Returns (x0, y0, premultiplied colour (h, w, 3), coverage alpha (h, w), unoccluded coverage sum):
    alpha already includes occlusion by the table top and the see-through net; the unoccluded sum
    is over the unclipped region, in pixels.
    """
    centres = positions @ camera.R.T + camera.t
    if (centres[:, 2] <= BALL_RADIUS + MIN_DEPTH).any():
        return None
    px = camera.project(positions)
    # distortion compresses (barrel), perspective stretches towards the edges by < 30 % here
    reach = camera.K[0, 0] * BALL_RADIUS / centres[:, 2] * 1.3 + 1.5
    x0, y0 = np.floor((px - reach[:, None]).min(axis=0)).astype(int)
    x1, y1 = np.ceil((px + reach[:, None]).max(axis=0)).astype(int) + 1
    if x1 <= 0 or y1 <= 0 or x0 >= camera.width or y0 >= camera.height:
        return None
    w, h = x1 - x0, y1 - y0
    rays = subpixel_rays(background.ray_map, x0, y0, w, h, BALL_SS).reshape(-1, 2)
    d = np.concatenate([rays, np.ones((len(rays), 1))], axis=1)  # camera frame, depth = ray parameter
    # per-ray arrays are (K, N), K exposure samples by N rays: summed along axis 0 they add in the order
    # ((a0 + a1) + a2 ...) that numpy keeps over a last axis shorter than 8 (its pairwise sum starts at 8),
    # so the sums are those of (N, K) arrays bit for bit, without a slow reduction per ray
    dd = rays[:, 0] * rays[:, 0] + rays[:, 1] * rays[:, 1] + 1.0  # (d * d).sum(axis=1), summed in its order
    dc = np.ascontiguousarray((d @ centres.T).T)  # (K, N); the product as it was, then transposed
    disc = dc**2 - dd * ((centres**2).sum(axis=1) - BALL_RADIUS**2)[:, None]
    light = camera.R @ LIGHT_DIR
    d_light, d_world = d @ light, d @ camera.R
    # only the rays that meet the ball at some instant of the exposure are shaded and occluded (about a
    # third of the box's); the others add exact zeros. The products above stay on all rays, so that every
    # value is what it was (a BLAS product of a subset may round differently).
    hit = disc >= 0
    rows = np.flatnonzero(hit.any(axis=0))
    dd, dc, disc, hit = dd[rows], dc[:, rows], disc[:, rows], hit[:, rows]
    d_light, d_world = d_light[rows], d_world[rows]
    s = (dc - np.sqrt(np.maximum(disc, 0.0))) / dd  # depth of the front surface
    # n . l with n = (s d - c) / r, without forming the normals
    n_dot_l = (s * d_light - (centres @ light)[:, None]) / BALL_RADIUS
    shade = BALL_AMBIENT + BALL_DIFFUSE * np.clip(n_dot_l, 0, None)
    coverage = hit.astype(float)
    o = camera.center
    if o[2] <= 0 or positions[:, 2].min() <= BALL_RADIUS + OCCLUSION_MARGIN:
        # the table top can hide the ball only where the ball dips to its plane (or the camera is below)
        with np.errstate(divide="ignore", invalid="ignore"):
            s_top = -o[2] / d_world[:, 2]
        p_top = o[:2] + s_top[:, None] * d_world[:, :2]
        on_top = (s_top > 0) & (np.abs(p_top[:, 0]) <= TABLE_HALF_WIDTH) \
            & (np.abs(p_top[:, 1]) <= TABLE_HALF_LENGTH)
        coverage = coverage * np.where(on_top & (s_top < s), 0.0, 1.0)
    if (np.sign(o[1]) * positions[:, 1]).min() <= BALL_RADIUS + OCCLUSION_MARGIN:
        # and the net only where the ball reaches its plane or the far side of it
        with np.errstate(divide="ignore", invalid="ignore"):
            s_net = -o[1] / d_world[:, 1]
        p_net = o[[0, 2]] + s_net[:, None] * d_world[:, [0, 2]]
        on_net = (s_net > 0) & (np.abs(p_net[:, 0]) <= TABLE_HALF_WIDTH + NET_OVERHANG) & (p_net[:, 1] >= 0) \
            & (p_net[:, 1] <= NET_HEIGHT)
        net_pass = np.where(p_net[:, 1] >= NET_HEIGHT - NET_TAPE, 0.0, NET_TRANSMISSION)
        coverage = coverage * np.where(on_net & (s_net < s), net_pass, 1.0)
    k = len(positions)
    fine = (h * BALL_SS, w * BALL_SS, 1)
    coverage_sum, shade_sum = np.zeros(len(d)), np.zeros(len(d))
    coverage_sum[rows], shade_sum[rows] = coverage.sum(axis=0), (coverage * shade).sum(axis=0)
    alpha = average_subsamples(coverage_sum.reshape(fine) / k, BALL_SS)
    shaded = average_subsamples(shade_sum.reshape(fine) / k, BALL_SS)
    return x0, y0, (shaded * BALL_BGR).astype(np.float32), alpha[..., 0].astype(np.float32), \
        hit.sum() / (k * BALL_SS**2)


def _noise_tables(sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Lookup tables byte -> (positive part, negative part) of Gaussian noise with std sigma.

    Uniform random bytes through the inverse normal CDF give Gaussian noise (quantised, tails cut
    at 2.7 sigma) for a fraction of the cost of floating-point normals.
    """
    values = np.round(ndtri((np.arange(256) + 0.5) / 256) * sigma)
    return np.clip(values, 0, 255).astype(np.uint8), np.clip(-values, 0, 255).astype(np.uint8)


def add_sensor_noise(image: np.ndarray, background: Background, rng: np.random.Generator) -> None:
    """Add Gaussian read noise to a uint8 image in place (saturating): a random window into the bank.

    A fresh random offset per frame is ~100x cheaper than fresh noise; successive frames get
    shifted copies of one noise field, which no per-frame detector can tell from independent noise.
    """
    size = image.size
    start = int(rng.integers(0, len(background.noise_up) - size + 1))
    cv2.add(image, background.noise_up[start:start + size].reshape(image.shape), dst=image)
    cv2.subtract(image, background.noise_down[start:start + size].reshape(image.shape), dst=image)


def _restore_table(image: np.ndarray, background: Background, shape: _Shape) -> None:
    """Put back the table where it lies in front of a just-drawn shape (a leg behind the table end)."""
    tx0, ty0, tx1, ty1, nearest = background.table_box
    if shape.depth <= nearest:
        return
    x0, y0, x1, y1 = shape.bbox
    x0, y0, x1, y1 = max(x0, tx0), max(y0, ty0), min(x1, tx1), min(y1, ty1)
    if x1 <= x0 or y1 <= y0:
        return
    in_front = background.table_depth[y0:y1, x0:x1] < shape.depth
    if in_front.any():
        np.copyto(image[y0:y1, x0:x1], background.image[y0:y1, x0:x1], where=in_front[..., None])


def render_frame(background: Background, camera: Camera, ball_positions: np.ndarray | None,
                 players_joints: Sequence[np.ndarray], paddles: Sequence[tuple[np.ndarray, np.ndarray]],
                 rng: np.random.Generator, *, looks: Sequence[PlayerLook] | None = None,
                 noise: bool = True) -> tuple[np.ndarray, BallTruth]:
    """One camera frame (H, W, 3) uint8 BGR and the ball's truth.

    ball_positions: (K, 3) ball centres spread over the exposure (K = 1: no motion blur), or None.
    players_joints: BODY_25 joints (25, 3) per person, table frame (NaN rows are not drawn).
    paddles: (position (3,), rotation (3, 3)) per paddle, table frame; see _paddle_shapes for the axes.
    looks: colours per person (default: a fixed palette); noise: add the background's sensor noise.
    """
    if looks is None:
        looks = make_player_looks(np.random.default_rng(0), len(players_joints))
    shapes = frame_shapes(camera, [np.asarray(j, float)[None] for j in players_joints], looks,
                          [(np.asarray(p, float)[None], np.asarray(r, float)[None]) for p, r in paddles])
    return render_shapes(background, camera, ball_positions, shapes[0] if shapes else [], rng, noise=noise)


def render_shapes(background: Background, camera: Camera, ball_positions: np.ndarray | None,
                  shapes: Sequence[_Shape], rng: np.random.Generator, *,
                  noise: bool = True) -> tuple[np.ndarray, BallTruth]:
    """render_frame with the people and paddles already turned into depth-sorted shapes (frame_shapes)."""
    image, truths = render_scene(background, camera, [ball_positions], shapes, rng, noise=noise)
    return image, truths[0]


def _ball_truth_and_layer(background: Background, camera: Camera, ball_positions: np.ndarray | None,
                          centre: np.ndarray | None = None):
    """(BallTruth without visibility, layer or None, camera depth of the mid-exposure centre) of a ball.

    centre: the mid-exposure centre for the truth and the depth (default: the mean of the positions).
    """
    if ball_positions is None or not len(ball_positions):
        return BallTruth(np.full(2, np.nan), 0.0, 0.0), None, -np.inf
    positions = np.asarray(ball_positions, float).reshape(-1, 3)
    mid = positions.mean(axis=0) if centre is None else centre
    depth = camera.depth(mid)[0]
    truth = BallTruth(camera.project(mid)[0], 0.0, camera.K[0, 0] * BALL_RADIUS / depth if depth > 0 else 0.0)
    return truth, _ball_layer(background, camera, positions), depth


def _hide_behind(occluders: np.ndarray, layer, nearer) -> None:
    """Mark in a ball's occluder mask where a nearer ball's layer covers it."""
    x0, y0 = layer[:2]
    nx0, ny0, _, alpha, _ = nearer
    h, w = occluders.shape
    ix0, iy0 = max(x0, nx0), max(y0, ny0)
    ix1, iy1 = min(x0 + w, nx0 + alpha.shape[1]), min(y0 + h, ny0 + alpha.shape[0])
    if ix1 > ix0 and iy1 > iy0:
        covered = alpha[iy0 - ny0:iy1 - ny0, ix0 - nx0:ix1 - nx0] > 0
        occluders[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0][covered] = 255


def render_scene(background: Background, camera: Camera, balls: Sequence[np.ndarray | None],
                 shapes: Sequence[_Shape], rng: np.random.Generator, *, noise: bool = True,
                 gain: float | None = None, centres: Sequence[np.ndarray | None] | None = None
                 ) -> tuple[np.ndarray, list[BallTruth]]:
    """One frame with any number of balls (each (K, 3) exposure positions, or None) and a truth per ball,
    then one per still ball of the background (with_still_balls), in its order.

    Every ball is drawn at its depth among the shapes and the other balls; a ball's visibility counts
    the shapes and balls in front of it. gain: the exposure's multiplier of every value before the
    sensor noise (twin.room's drift and flicker; None: none, and no pass over the image). centres: per
    ball, its mid-exposure centre for its truth where it is drawn from fewer positions than it had
    (None, or a None: the mean of its positions).
    """
    centres = [None] * len(balls) if centres is None else centres
    prepared = [_ball_truth_and_layer(background, camera, b, c) for b, c in zip(balls, centres, strict=True)]
    still = background.still_balls
    if still is None:
        image = background.image.copy()
        truths = _draw_balls(image, background, camera, prepared, shapes)
    else:
        image = still.image.copy()
        redrawn = _still_balls_to_redraw(still, shapes, [layer for _, layer, _ in prepared])
        for i in redrawn:  # back to the lab's pixels, then drawn with the others as if never baked in
            x0, y0, x1, y1 = np.clip(still.boxes[i], 0, [camera.width, camera.height] * 2)
            image[y0:y1, x0:x1] = background.image[y0:y1, x0:x1]
        prepared += [still.prepared[i] for i in redrawn]
        truths = _draw_balls(image, background, camera, prepared, shapes)
        still_truths = list(still.truths)
        for i, truth in zip(redrawn, truths[len(balls):], strict=True):
            still_truths[i] = truth
        truths = truths[:len(balls)] + still_truths
    if gain is not None:
        # rounds half to even where a LUT of round(v gain) rounds up: 1 DN apart at 7e-6 of (value, gain)
        # pairs (gains 0.8-1.2), at half a LUT's cost (0.085 against 0.155 ms at 480x360, 0.24 with the table)
        cv2.convertScaleAbs(image, image, gain)
    if noise:
        add_sensor_noise(image, background, rng)
    return image, truths


def _draw_balls(image: np.ndarray, background: Background, camera: Camera, prepared: Sequence,
                shapes: Sequence[_Shape]) -> list[BallTruth]:
    """Draw the shapes and the balls ((truth, layer, depth) of _ball_truth_and_layer) into the image, each
    at its depth; the balls' truths with their visibility."""
    truths, layers, depths = (list(column) for column in zip(*prepared, strict=True)) if prepared \
        else ([], [], [])
    pending = sorted((i for i, layer in enumerate(layers) if layer is not None), key=lambda i: -depths[i])
    drawn: list[tuple[int, np.ndarray]] = []  # (ball, its occluder mask), farthest first
    boxes = np.array([shape.bbox for shape in shapes], dtype=np.int64).reshape(-1, 4)
    # per shape, the drawn balls (and their occluder masks) whose box it overlaps: one array test per ball
    # instead of a test per shape and ball (twin.room's extra balls made those ~120 Python calls a frame)
    covering: dict[int, list[tuple[int, np.ndarray]]] = {}

    def composite_behind(depth: float, next_shape: int) -> None:
        """Draw the pending balls farther than depth, farthest first (the shapes from next_shape on are
        nearer)."""
        while pending and depth < depths[pending[0]]:
            i = pending.pop(0)
            for j, occluders in drawn:  # the balls drawn before lie behind this one
                _hide_behind(occluders, layers[j], layers[i])
            drawn.append((i, _composite_ball(image, layers[i])))
            box = np.array([_layer_box(layers[i])])
            for k in (np.flatnonzero(_boxes_overlap(boxes[next_shape:], box)[:, 0]) + next_shape).tolist():
                covering.setdefault(k, []).append(drawn[-1])

    tx0, ty0, tx1, ty1, nearest = background.table_box
    for k, shape in enumerate(shapes):
        if pending:
            composite_behind(shape.depth, k)
        shape.draw(image, shape.colour)
        # _restore_table's own first tests, here: most shapes are nearer than the table or beside it,
        # and a call per shape cost more than the test
        if shape.depth > nearest:
            sx0, sy0, sx1, sy1 = shape.bbox
            if sx0 < tx1 and sy0 < ty1 and sx1 > tx0 and sy1 > ty0:
                _restore_table(image, background, shape)
        for i, occluders in covering.get(k, ()):
            shape.draw(occluders, 255, offset=layers[i][:2])
    composite_behind(-np.inf, len(shapes))
    for i, occluders in drawn:
        x0, y0, _, alpha, unoccluded = layers[i]
        visible = alpha * (occluders == 0)
        inside = visible[max(0, -y0):max(0, camera.height - y0), max(0, -x0):max(0, camera.width - x0)]
        truths[i] = BallTruth(truths[i].pixel, float(min(1.0, inside.sum() / unoccluded)),
                              truths[i].radius_px)
    return truths


@dataclass(frozen=True)
class StillBalls:
    """Balls that never move (twin.room's balls resting on the floor or the table), drawn once per camera.

    render_scene starts every frame from `image` and draws a still ball again, from its cached layer and
    the ordinary way, only in a frame where a shape or another ball overlaps its box (with the still balls
    that overlap it): the pixels and truth of drawing every ball in every frame, bit for bit, for a box
    test a frame instead of a ray cast (0.12-0.22 ms) per ball.
    """

    image: np.ndarray  # the background's image with the still balls composited
    prepared: tuple  # per ball: _ball_truth_and_layer's (truth without visibility, layer or None, depth)
    truths: tuple[BallTruth, ...]  # per ball, with its visibility among the still balls alone
    boxes: np.ndarray  # (m, 4) int x0, y0, x1, y1 (exclusive) of each ball's layer; NO_BOX without one
    linked: np.ndarray  # (m, m) bool: ball j is drawn again whenever ball i is (overlaps, transitively)


NO_BOX = (2**30, 2**30, -2**30, -2**30)  # overlaps nothing


def _layer_box(layer) -> tuple[int, int, int, int]:
    if layer is None:
        return NO_BOX
    x0, y0, _, alpha, _ = layer
    return x0, y0, x0 + alpha.shape[1], y0 + alpha.shape[0]


def _boxes_overlap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, m) whether boxes a (n, 4) and b (m, 4) (x0, y0, x1, y1, exclusive) share a pixel."""
    a, b = a[:, None], b[None, :]
    return (a[..., 0] < b[..., 2]) & (a[..., 1] < b[..., 3]) & (a[..., 2] > b[..., 0]) \
        & (a[..., 3] > b[..., 1])


def with_still_balls(background: Background, camera: Camera, positions: Sequence[np.ndarray]) -> Background:
    """The background with balls at rest (each a (3,) centre, table frame) drawn in (see StillBalls)."""
    prepared = tuple(_ball_truth_and_layer(background, camera, np.asarray(p, float).reshape(1, 3))
                     for p in positions)
    image = background.image.copy()
    truths = _draw_balls(image, background, camera, prepared, [])
    boxes = np.array([_layer_box(layer) for _, layer, _ in prepared], dtype=np.int64).reshape(-1, 4)
    linked = _boxes_overlap(boxes, boxes) | np.eye(len(boxes), dtype=bool)
    while True:  # the transitive closure: a ball drawn again draws again every still ball it overlaps
        wider = (linked.astype(np.int64) @ linked.astype(np.int64)) > 0
        if (wider == linked).all():
            break
        linked = wider
    return replace(background, still_balls=StillBalls(image, prepared, tuple(truths), boxes, linked))


def _still_balls_to_redraw(still: StillBalls, shapes: Sequence[_Shape], layers: Sequence) -> np.ndarray:
    """Indices of the still balls that a shape's or a ball's box overlaps, with those linked to them."""
    boxes = [shape.bbox for shape in shapes] + [_layer_box(layer) for layer in layers if layer is not None]
    if not boxes or not len(still.boxes):
        return np.zeros(0, int)
    touched = _boxes_overlap(np.array(boxes), still.boxes).any(axis=0)
    return np.flatnonzero(still.linked[touched].any(axis=0))


def _composite_ball(image: np.ndarray, layer) -> np.ndarray:
    """Blend the ball layer onto the image (clipped) and return a blank occluder mask of its region."""
    x0, y0, colour, alpha, _ = layer
    h, w = alpha.shape
    ix0, iy0 = max(x0, 0), max(y0, 0)
    ix1, iy1 = min(x0 + w, image.shape[1]), min(y0 + h, image.shape[0])
    if ix1 > ix0 and iy1 > iy0:
        a = alpha[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0, None]
        roi = image[iy0:iy1, ix0:ix1].astype(np.float32)
        blended = roi * (1 - a) + colour[iy0 - y0:iy1 - y0, ix0 - x0:ix1 - x0]
        image[iy0:iy1, ix0:ix1] = np.clip(blended + 0.5, 0, 255).astype(np.uint8)
    return np.zeros((h, w), np.uint8)


JPEG_CHROMA = {"444": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444, "422": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_422,
               "420": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420}


def encode_jpeg(image: np.ndarray, quality: int = 90, chroma: str = "444") -> bytes:
    """JPEG bytes of a BGR image (libjpeg through OpenCV).

    chroma: subsampling "444", "422" or "420". Full-resolution chroma (the machine-vision
    cameras' option) is the default: at 480x360 the ball is ~3-4 px across, and 4:2:0 averages
    its colour over 2x2 blocks until only 1-3 pixels stay saturated enough to be told from skin.
    A restart marker ends every row of MCUs (cjpeg's `-restart 1`), so that a reader can decode the
    rows around a tracked ball alone (pingpong.io.jpeg.decode_jpeg_rows); the pixels are those
    without markers, the file ~0.4 % larger (36,211 -> 36,365 bytes, a 480x360 twin frame).
    """
    mcu_width = 8 if chroma == "444" else 16
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality),
                                           cv2.IMWRITE_JPEG_SAMPLING_FACTOR, JPEG_CHROMA[chroma],
                                           cv2.IMWRITE_JPEG_RST_INTERVAL, -(-image.shape[1] // mcu_width)])
    if not ok:
        raise RuntimeError("cv2.imencode failed to encode a JPEG frame")
    return buf.tobytes()
