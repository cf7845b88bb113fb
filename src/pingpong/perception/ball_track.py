"""Ball detection without a green screen (config perception.ball.method: track): candidates from motion,
colour and size in every frame, linked offline into ballistic tracks; a frame's ball is the candidate on
the best track through it, or none.

The field. TrackNet (Huang et al. 2019; v2, v3) feeds 3 consecutive frames to a U-Net heat-map network
and reads the ball from the peak: it learns motion and appearance together, needs labelled frames of the
sport and a GPU (~10-40 ms a frame on a GPU at 512x288), and fails on balls unlike its training (colour,
size, camera height). The classical trackers (Yan, Christmas & Kittler 2005-2008 for tennis; Hawk-Eye's
published outline; the many frame-difference ping-pong trackers) take candidate blobs of a foreground
(background-subtracted or frame-differenced) image, often colour-gated, and resolve which candidate is the
ball by its trajectory: tracklets grown from triplets of candidates with a constant-acceleration (projected
ballistic) model, then the tracklets linked by a graph or a dynamic programme into the ball's path. Their
failure modes are the candidate stage's: a ball not in the foreground (resting, or moving less than its
size between frames), a ball washed out by motion blur, and other moving things of the ball's look. This
module is a classical tracker of that family (no labels, CPU only), built on the colour test of
pingpong.perception.detection (the paper's appendix method, `method: colour`).

Inputs: a camera's frames in order (any reader of pingpong.io.camera_streams) with their time_ns (the
gates are in seconds: a 30 fps club camera and the 100 Hz twin alike) and the ball's colour test
(detection.ball_detector of config perception.ball). Outputs: a DETECTIONS table (a row per frame) and a
BALL_CANDIDATES table (every candidate weighed, kept or the reason it was refused).

1. Candidates (`frame_candidates`), per frame on the image decoded at 1/`track_reduction` (>= TRACK_WIDTH_PX
   wide: 1280x720 -> 640x360, decoded at 1/2 inside libjpeg; 480x360 whole). A candidate pixel is
   ball-coloured AND differs from the background: a running average of the frames (`Background`, time
   constant background_s of stream time, started from the stream's scene image, detection.scene_image)
   by at least motion_min in the grey level of the absolute BGR difference. So a static ball-coloured
   box, a sign or a resting ball is no candidate once the background has taken it in. Ball-coloured is
   first the configured colour test (detection._colour_mask; its blobs within the area range are
   candidates unless a red/yellow seam, detection._is_seam); then, 3 px or more apart from those blobs, a
   loosened test (`loosened`: the blur test's saturation floor, S 120 from 170, and the value floor times
   washed_value_factor, V 82 from 110), whose blobs from the minimum area to the blur test's maximum
   with a pixel at its peak saturation (150) are candidates too, unless on skin without a ball's core
   (detection._skin_without_core): blur washes a fast ball's saturation and, over a dark background, its
   value (detection's "Fast far balls": streaks over the twin's table top reach V 95-120). Loosening
   first everywhere merged the ball with the hand holding it (skin: S 95-140): recall 59 % on the twin
   stream below. Blobs touching the image's border are refused ('edge': the skin test's ring is cut
   there; a near player's skin at the bottom edge made 11.7 % false detections on the benchmark's stream),
   as are blobs above the area range ('size'). The best candidates_per_frame by ball-likeness (`_score`:
   the mean of the blob's CORE_PX highest values of the detector's centre channel, an orange ball's
   saturation, over 255, times its fill of its moment ellipse, detection._fill, at most 1: the twin's
   ball 0.7-0.95, skin 0.2-0.6) times the share of its pixels that differ from the previous frame by
   motion_min (`_fresh_share`, on the blobs' boxes of frames with more blobs than the cap: a flying ball
   leaves its own place each frame, slowly moving orange clothing mostly does not) are linked ('rank' for
   the others), each at its sub-pixel centre by
   detection._weighted_centre on the reduced image, in full-resolution pixels. Ranked by likeness alone,
   the bystander's shirt crowded a fast ball out of every other frame (twin.room seed 5 camera 2:
   recall 98.42 -> 98.92 %, false 0.36 -> 0.18 %; held-out seed 6 cameras 0 and 2 false 1.27 -> 0.42 and
   1.06 -> 0.35 %, camera 2 recall 99.34 -> 97.92 %).
2. Tracks (`link_tracks`), offline over the whole stream. Every candidate not taken by a track of 3 or
   more points seeds a track; a track predicts the next frame's ball from a constant-acceleration fit (per
   image axis, in time) of its last FIT_POINTS points (constant velocity from 2 points; from 1 point,
   anything within max_speed_px_s), and takes the candidates in its gate, gate_px (the centres' noise) +
   accel_px_s2 dt^2 / 2 (acceleration the fit misses, over the time dt since its last point: the gate
   grows with a gap and with the frame interval). Several candidates in a gate branch the track (multiple
   hypotheses, at most MAX_BRANCHES a track); of the hypotheses with the same last 3 points the one with
   the most points since the latest start among them lives on (a track carried over a gap loses to one
   that followed the ball through it) and the others end before that start (`_pruned`). A track ends
   after max_gap_s without a point, and loses end runs of fewer than EDGE_RUN points beyond a gap
   (`_trimmed`: a gate grown over a bounce takes the bounce's first point or a hand beside the ball;
   on the stream of tests/test_detection.py's camera 1, false detections 0.18 -> 0.03 %). Each track is
   then judged by what it does (`judge`): fewer than min_track_points points, 'short' ('lone' for one);
   a median speed below a tenth of min_speed_px_s, 'static' (a resting ball); more than MAX_HELD_SHARE of
   its windows of FIT_POINTS points held, 'slow' (a held ball moving with the hand, a rolling ball): a
   window is held when its constant-acceleration fit is slower than min_speed_px_s at its middle and does
   not fall (downward acceleration below min_fall_px_s2, or above max_fall_px_s2: noise, as a 5-point
   jitter of a hidden ball fitting 20,000, not gravity). Judged per window because a toss slowing to its
   apex or a flight along the camera's axis is slow but falls: the track's median speed below
   min_speed_px_s refused held-out twin.room seed 6 camera 3's slow serve toss whole (recall 91.45 ->
   99.69 %) and the tiny run's flights of 2-4 m/s along the camera axis (at 02f9b33, 349 / 432 / 809
   frames of cameras 0-2 refused 'slow', the lead's measurement); a held share of 0.5 let a hidden
   ball's jitter in (falls -5,800..2,800 over its 9 windows, 4 held: false 0 -> 0.98 %). min_speed_px_s
   100 rather than 300, since min_fall_px_s2 refuses the held ball: on the tiny run with twin.room
   (config/test/tiny.yaml with config/twin_room.yaml's room, since 33196b3 config/config.yaml's, less its
   table ball; cameras 0-2) recall 95.7 / 96.3 / 96.6 -> 97.0 / 99.0 / 98.5 %, false 0 / 0.09 / 0.23 ->
   0.20 / 0.09 / 0.28 %
   (at 02f9b33, judged by the track's median speed, the lead's: 94.1 / 93.6 / 86.5 % at 300; 98.2 /
   98.9 / 98.2 %, false 0.18 / 0.25 / 0.38 % at 100), twin.room seeds 5 and 6 recall unchanged, false
   0 -> 0.18 % on seed 5 camera 2, the rest unchanged (seed 6 camera 2's 0.35 %: a 5-point track
   falling 34,000 px/s^2, refused at 600). Tried and dropped: cutting a
   track at its runs of 7 or more windows not held (to free seed 5 camera 0's serve toss from the held
   ball's track: 98.14 -> 99.13 %) made a hand swinging the second ball a flight (seed 6 camera 0 false
   0.07 -> 5.06 %); a held share of 0.5 (seed 6 camera 3 false 0.98 %); refusing a median fall above
   max_fall_px_s2 (plain twin recall 99.38 -> 97.74 % on camera 0: near flights fall faster). An RMS
   residual of its constant-acceleration fits over windows of
   FIT_POINTS points above max_residual_px, or a median downward acceleration of those fits below
   min_fall_px_s2, 'non_ballistic' (arms, clothing; a ball moving in a hand, which does not fall: the
   twin's ball in play falls at 3,000-3,400 px/s^2 at REFERENCE_WIDTH at its median, twin.room's held
   second ball at -180 to 230; without this test it made 9.9 % false detections on twin.room's camera
   1, and a local residual cannot tell it: at 100 Hz any hand's path is a parabola over 7 points); a
   median ball-likeness of
   its candidates below min_likeness, 'colour' (a moving arm's skin: 0.26-0.37, 1.3 % false detections
   on the benchmark's 1280x720 stream without this test; the twin's ball 0.57 at its 0.5th percentile,
   0.83-0.9 at its median). The others are flights,
   scored by their candidates' summed ball-likeness less their residual in gate units; they are taken
   best first, each on the frames no better flight has taken where it still has min_track_points there
   (`choose_points`: hypotheses share points, and a bounce's point may end one flight and start the
   next; weighted interval scheduling over whole tracks lost a flight to a branch overlapping it by a
   few frames: recall 72 % against 96 % before the other changes). A frame's ball is the candidate of
   the flight that took it; candidates on flights not taken are 'off_track'.
3. Ends (`grown`): each run of EDGE_RUN or more consecutive frames of chosen balls grows forwards and
   backwards, frame by frame, onto the nearest candidate in the gate of its end's constant-acceleration
   prediction, among the best candidates_per_frame and those ranked out ('rank'), in frames without a
   ball. Linking goes forwards only, so a flight's first point after a bounce or a hit (on the flight,
   but ending the one before) and ends too short for a track of their own were missed, as were balls
   ranked out by moving orange clothing in the midst of a flight (twin.room seed 5 camera 2: 77 misses
   -> 44). Letting 'rank' candidates extend tracks while linking instead found more (camera 2 98.92 %)
   but linked the bystander's shirt into 5-point flights (false 0.33 -> 0.60 %).

Settings: TrackSettings (config perception.ball.track), px values at detection.REFERENCE_WIDTH, scaled
with the image's width.

Measured (recall: visible balls, visibility >= 0.5, detected within 5 px; false: frames with a detection
farther than 5 px from the ball or with no ball visible; the colour method beside it):
- the twin, 2 rallies, 480x360 JPEG q90 at 100 Hz, seed 5 (tests/test_detection.py's session), cameras
  0-3: recall 99.38 / 99.69 / 99.35 / 99.52 % (colour 99.93 / - / 97.56 / - %), false 0 / 0 / 0 / 0 %,
  median error 0.113-0.115 px (as the colour method's: the same centre). The misses are the 1-5 frames
  at a flight's end by a hit or behind a player, too few for a track of their own. Seed 7, camera 0,
  1280x720: 99.33 % (colour 99.90 %), false 0.038 % (colour 0.038 %), median error 0.188 px.
- the harder twin (twin.room, config/config.yaml's less its table ball: wood, a sign, orange clothing, the
  server's second ball held 80 % of the time, balls on the floor and rolling, gain drift and mains flicker),
  the same session and cameras 0-3 at 480x360: recall 98.14 / 99.48 / 98.92 / 99.48 %, false 0 / 0 / 0.18 /
  0 %
  (before `grown`, the _pruned fix and the fresh ranking: 96.50 / 99.16 / 97.24 / 98.76 %, false
  0 / 0 / 0.33 / 0 %; the colour method: recall 0 on each, a distractor in 99.9-100 % of the frames).
  Held out (seed 6, 1,422 frames, not looked at while choosing): 99.79 / 100 / 97.92 / 91.45 %, false
  0.42 / 0 / 0.35 / 0 % (before: 99.04 / 98.74 / 96.60 / 85.44 %, false 1.13 / 0 / 0.91 / 0 %). With
  'slow' judged per window (seed 6 camera 3 looked at to make it), min_speed_px_s 300: seed 5 98.14 /
  99.58 / 98.92 / 99.48 %, false 0 / 0 / 0 / 0 %; seed 6 99.79 / 100 / 97.92 / 99.69 %, false 0.07 / 0 /
  0.35 / 0 %; at 100 (the default) the same recall, false 0 / 0 / 0.18 / 0 and 0.07 / 0 / 0.35 / 0 %;
  the plain twin unchanged at either (99.38 / 99.69 / 99.35 / 99.52 %, false 0).
  The tiny run's misses at 100 are still mostly 'slow' (98 / 57 / 63 frames of 199 / 67 / 96) and, on
  camera 0, 'non_ballistic' (71): windows of a slow flight at 100 Hz whose fit's fall is noise. Below
  issue 49's 99 %: seed 5 camera 0's ball tossed slowly beside the held second ball (3198-3225: its
  track takes the held ball's points and is judged slow), flight ends of 1-5 frames beside a hit that
  no run reaches; seed 6 camera 2 (19 misses). Before the per-window judgment, seed 5 camera 2's
  bystander's shirt made 6 false frames, and 69 of seed 6 camera 3's 84 misses were one slow toss
  rising to its apex at <= 3 px a frame, judged 'slow' whole.
- bench_ball_detectors.py's streams (seed 1, the ball bucket's backgrounds): 480x360 recall 99.80 %,
  false 0 (colour 100 %, 0); 1280x720 99.71 %, false 0 (colour 100 %, 0).
Measured by calling detect_stream on streams rendered as tests/test_detection.py's fixture and
test_ball_track.py's twin.room test do (the session, rig and room of `seed`, one camera, 480x360);
tests/test_ball_track.py holds the twin's camera 0, twin.room's
camera 2 and the club-room clip.
- a 1280x720 30 fps club-room clip (tests/test_ball_track.py: a plain room, a static orange-brown box at
  V 116, a ball held in a hand moving 50 px/s, a ballistic ball blurred over 1/60 s): the flying ball in
  76 of its 76 frames, median error 0.10 px, nothing else ever; the held ball refused as slow in all 120
  frames; the colour method takes the box in every frame and the flying ball in none.

Cost (benchmarks/bench_ball_detectors.py, one thread, JPEG q90 frames in memory, decoding included, the
stage's scene image and the offline linking too; 1,494 twin frames, best of 3 interleaved rounds on the
shared 2-core machine at load ~4): 1280x720, 162 frames/s (6.2 ms a frame: the 1/2 decode 3.2-3.5 ms,
the masks and blobs on 640x360 1.3-1.9 ms, the scene image's 25 full decodes 0.85 ms a frame of this
short stream, linking and judging 0.2 ms), 0.55 of the colour method's 293 (which decodes only its
window's rows while it tracks the ball); 480x360, 325 frames/s (3.1 ms), 0.23 of colour's 1,423. With
`grown` and the fresh ranking (0054170 and after, the same command): 1280x720 168 frames/s, 0.49 of
colour's 344; 480x360 304 frames/s, 0.25 of colour's 1,239 (the machine busier than before: colour
fell too). Where 480x360's time went (cProfile of detect_stream on the twin's camera 0, 1,500 frames,
5.4 s): JPEG decoding 28 %, the HSV and grey conversions 9 %, the colour tests' inRange 8 %, blobs
(findContours, drawContours, _blobs) 14 %, the rest numpy and Python per blob. Made cheaper with the
same output (the DETECTIONS and BALL_CANDIDATES tables value for value those of 6fb8228 on the benchmark's
streams at both sizes, tests/test_ball_track.py's twin camera 0 and twin.room seeds 5 and 6, cameras 0-3,
1,422-3,340 frames each): the moving mask first, then HSV and the colour tests only on its pixels inside the
BGR box of the colours the tests pass (`_moving_colour`, `_bgr_box`: the orange ball's loosened test B 0-135,
G 21-212, R 82-255, 27 % of all colours; 0.45 -> 0.29 ms a frame); HSV only around the blobs; a washed blob
skipped before it is drawn where its box holds no pixel at the blur test's peak saturation (27 of the
benchmark's 29 blobs a frame); the loosened mask cleared around each colour-test blob on its patch (a
whole-frame dilation and boolean index: 0.1-0.3 ms); a track's fit made once (3 of 4 predictions are of a
track carried over a frame without a point); _pruned choosing only among tracks that share their last 3
points; np.cov and np.median by their own operations (detection._covariance, _median: the same floats).
`bench_ball_detectors.py --sizes 480x360 --against 6fb8228` (this and the revision in the same rounds):
480x360 385 against 320 frames/s, 1.20x (2.60 ms a frame; 0.26 of colour's 1,462); with --sizes 1280x720, 165
against 146 frames/s, 1.13x (6.07 ms; 0.48 of colour's 340). On twin.room (seed 5 camera 2, 1,500 frames, the
stream of tests/test_ball_track.py's twin.room test, timed as --against does in one process, best of 2): 5.21
-> 3.86 ms a frame, 1.35x (3 to 4 times the plain twin's blobs and tracks). Not 2x at 480x360: what is left
(each stage timed on the benchmark's 480x360 stream, 2.6 ms) is JPEG decoding 0.9 ms and the scene image's
decodes 0.1 ms, the running background (a float32 mean, its difference and update over the whole frame) 0.23
ms, the candidates 1.2 ms (the masks 0.3, 2 findContours 0.15, per blob the rest), linking 0.1 ms; decoding
and the background alone are 1.2 ms, and a cheaper decode (a reduced one, or row bands) changes what is found.
Issue 49's bar is 100 frames/s per core at 1280x720 with decoding. An H.264 video is decoded whole by PyAV and
shrunk (io.camera_streams.VideoFrame): not measured here.

Failure modes (by construction): a ball that rests, or moves slower than min_speed_px_s without a
measurable fall over a quarter of its track, is never reported (the ball in play moves and falls); a
ball in front of a background of its own colour differs too little from the background; a second ball
tossed along a ballistic path during play is a valid track and
competes by its candidates' ball-likeness; a whole-frame exposure change makes every ball-coloured static
thing a candidate for about background_s (refused as static, but they crowd the per-frame candidate
cap); a moving camera has no background; a ball caught or slowed by a hand is no flight. Not measured on
issue 49's real clip (not in this repository).
"""

import bisect
import functools
import logging
from collections.abc import Iterable
from dataclasses import dataclass, replace

import cv2
import numpy as np
import pandas as pd

from pingpong.perception import detection
from pingpong.perception.detection import (
    CORE_PX,
    REFERENCE_WIDTH,
    BallDetector,
    _around,
    _blobs,
    _fill,
    _in_colour_range,
    _is_seam,
    _opened,
    _opening_side,
    _skin_without_core,
    _weighted_centre,
)

log = logging.getLogger(__name__)

TRACK_WIDTH_PX = 640  # px: the narrowest image candidates are searched on (1280x720 at 1/2)
FIT_POINTS = 7  # a track's last points fitted with constant acceleration to predict the next
EDGE_RUN = 3  # points in consecutive frames that a track's end beyond a gap needs (_trimmed)
MAX_BRANCHES = 3  # candidates in one gate that each extend a track (the nearest first)
MAX_TRACKS = 200  # live tracks kept at once (the longest first): a bound on the hypotheses
MAX_HELD_SHARE = 0.25  # of a track's windows slow and not falling (judge): more, and it is no flight
HSV_MARGIN = 3  # px around a blob's box whose HSV its tests read (_hsv_around)
_APART = np.ones((5, 5), np.uint8)  # a washed blob's pixels lie >= 3 px from the colour test's blobs
CANDIDATE_COLUMNS = ("time_ns", "u", "v", "area_px", "score", "kept", "reason")


@dataclass(frozen=True)
class TrackSettings:
    """The track method's settings; px at REFERENCE_WIDTH, scaled with the image's width."""

    washed_value_factor: float = 0.75  # of the colour test's value floor, for a washed ball's pixels
    motion_min: int = 12  # grey level of |frame - background| from which a pixel moves
    background_s: float = 0.5  # s, time constant of the running background
    candidates_per_frame: int = 4  # the best blobs of a frame kept as candidates
    max_speed_px_s: float = 9000.0  # a one-point track's reach: px/s at REFERENCE_WIDTH
    gate_px: float = 6.0  # px at REFERENCE_WIDTH: a prediction's error with no time elapsed
    accel_px_s2: float = 30000.0  # px/s^2 at REFERENCE_WIDTH: acceleration the model misses
    max_gap_s: float = 0.1  # s without a point after which a track ends
    min_track_points: int = 5  # fewer points: too short to tell a ball from a look-alike
    min_speed_px_s: float = 100.0  # px/s at REFERENCE_WIDTH: a slower window not falling is held (judge)
    max_residual_px: float = 3.0  # px at REFERENCE_WIDTH: RMS of a track's constant-acceleration fits
    min_likeness: float = 0.5  # a flight's median ball-likeness (_score) of its candidates
    min_fall_px_s2: float = 600.0  # px/s^2 at REFERENCE_WIDTH: a flight's median downward acceleration
    max_fall_px_s2: float = 10000.0  # px/s^2 at REFERENCE_WIDTH: a slow window falling faster is noise


def track_settings(track: dict | None) -> TrackSettings:
    """TrackSettings of config perception.ball.track (its keys are the fields; missing ones default)."""
    return replace(TrackSettings(), **(track or {}))


def track_reduction(width: int) -> int:
    """The decoder reduction (1, 2, 4 or 8) of a stream `width` px wide for candidates: the largest that keeps
    the image >= TRACK_WIDTH_PX wide."""
    return next((r for r in (8, 4, 2) if width / r >= TRACK_WIDTH_PX), 1)


def loosened(detector: BallDetector, settings: TrackSettings) -> BallDetector:
    """The colour test of `detector` loosened for a washed ball's pixels: its blur test's saturation floor
    (detection's "Fast far balls") and its value floor times washed_value_factor, with no scene contrast
    (the running background does that job)."""
    return replace(detector, saturation_min=detector.blur_saturation_min, scene_contrast_min=0,
                   value_min=int(detector.value_min * settings.washed_value_factor))


class Background:
    """A running average of a stream's frames (float32 BGR), its time constant in seconds of stream time."""

    def __init__(self, image: np.ndarray, time_constant_s: float):
        self.mean = image.astype(np.float32)
        self.time_constant_s = time_constant_s
        self.last_ns = None

    def moving(self, image: np.ndarray, time_ns: int, threshold: int) -> np.ndarray:
        """uint8 0/255 mask of the pixels of `image` that differ from the background by `threshold` (grey
        level of the absolute difference); then the background takes in the image."""
        difference = cv2.cvtColor(cv2.absdiff(image, cv2.convertScaleAbs(self.mean)), cv2.COLOR_BGR2GRAY)
        dt = 0.0 if self.last_ns is None else max(time_ns - self.last_ns, 0) * 1e-9
        cv2.accumulateWeighted(image, self.mean, float(-np.expm1(-dt / self.time_constant_s)))
        self.last_ns = time_ns
        return cv2.threshold(difference, threshold - 1, 255, cv2.THRESH_BINARY)[1]


def _score(hsv: np.ndarray, x: int, y: int, blob: np.ndarray, channel: int) -> float:
    """Ball-likeness of a blob: the mean of its CORE_PX highest values of HSV `channel` (the detector's
    centre channel: an orange ball's saturation) over 255, times its fill of its moment ellipse
    (detection._fill, at most 1)."""
    values = hsv[y:y + blob.shape[0], x:x + blob.shape[1], channel][blob > 0]  # row by row, as np.nonzero
    # the integer sum over CORE_PX: ndarray.mean's float, without its cost
    core = int(np.partition(values, -CORE_PX)[-CORE_PX:].sum()) / CORE_PX if len(values) > CORE_PX \
        else values.max()
    return float(core) / 255 * min(_fill(blob)[0], 1.0)


def frame_candidates(image: np.ndarray, reduction: int, detector: BallDetector, moving: np.ndarray,
                     settings: TrackSettings, previous: np.ndarray | None = None) -> list[tuple]:
    """Candidates (u, v, area_px, score, reason) of an image decoded at 1/reduction, u, v and area in
    full-resolution pixels: reason '' for the best candidates_per_frame, 'rank' for the others, 'size' for
    moving ball-coloured blobs above the area range, 'colour' for blobs of the colour test that are a
    red/yellow seam (detection._is_seam) and washed blobs on skin without a ball's core
    (detection._skin_without_core: JPEG lifts skin's saturation to 150-177 beside a hand), 'edge' for
    blobs touching the image's border (the skin test's ring is cut there, and a ball cut by the border is
    centred on its visible part)."""
    height, width = image.shape[:2]
    strict, loose, peaks = _moving_colour(image, moving, _colour_tests(detector, settings))
    hsv = np.empty_like(image)  # HSV only around the blobs (_hsv_around): all that is read of it
    min_area, max_area, _ = detector.scaled(width)
    if reduction > 1:
        min_area *= detector.candidate_area
    found = []
    for x, y, w, h, blob, area in _blobs(strict, min_area, np.inf):
        _hsv_around(image, hsv, x, y, w, h)
        reason = "size" if area > max_area else "colour" if \
            detector.seams and _is_seam(hsv, x, y, blob, detector.saturation_min) else ""
        found.append((x, y, blob, area, reason))
        # a washed ball's blob lies apart from these: the blob and 2 px around it (_APART) leave `loose`, on
        # the blob's patch (a mask of the whole frame dilated and indexed: 0.1-0.3 ms a frame at 480x360)
        _, _, patch, core = _around(loose, x, y, blob, _APART.shape[0] // 2)
        patch[cv2.dilate(core, _APART) > 0] = 0
    # a washed ball's blob: of the loosened test with a pixel at the blur test's peak
    washed_area = detector.blur_max_area_px * (width / REFERENCE_WIDTH) ** 2
    for x, y, w, h, blob, area in _blobs(loose, min_area, washed_area, seeds=peaks):
        _hsv_around(image, hsv, x, y, w, h)
        if hsv[y:y + h, x:x + w, 1][blob > 0].max() >= detector.blur_peak_saturation:
            found.append((x, y, blob, area, "colour" if _skin_without_core(hsv, x, y, blob, detector, width)
                          else ""))
    found = [(x, y, blob, area, reason or ("edge" if min(x, y) == 0 or x + blob.shape[1] == width
                                           or y + blob.shape[0] == height else ""))
             for x, y, blob, area, reason in found]
    if previous is not None and sum(not reason for *_, reason in found) > settings.candidates_per_frame:
        found = [(x, y, blob, area, reason, _fresh_share(image, previous, x, y, blob, settings.motion_min))
                 for x, y, blob, area, reason in found]  # the cap chooses: rank by motion too
    else:
        found = [(*blob, 1.0) for blob in found]
    return _ranked(hsv, found, reduction, detector, settings)


@functools.lru_cache(maxsize=8)  # per frame otherwise: 0.007 ms each
def _colour_tests(detector: BallDetector, settings: TrackSettings) -> tuple[BallDetector, ...]:
    """The colour tests of frame_candidates: the detector's, the loosened one, and the loosened one's pixels
    at the blur test's peak saturation, unopened (a washed blob needs one of these: a blob whose box
    holds none is skipped undrawn, 27 of the 29 blobs a frame on bench_ball_detectors.py's 480x360 stream)."""
    loose = loosened(detector, settings)
    return detector, loose, replace(loose, saturation_min=detector.blur_peak_saturation, open_px=0.0)


def _moving_colour(image: np.ndarray, moving: np.ndarray, tests: tuple[BallDetector, ...]) -> list:
    """uint8 0/255 mask of each colour test (detection._colour_mask without scene contrast) on `image` AND
    `moving`, with the HSV conversion and the tests run only on the moving pixels (and, for a test that
    opens its mask, those within the opening's reach of them) in the BGR box of the colours the tests
    pass (`_bgr_box`): equal to the tests run on the whole image, ANDed with moving."""
    height, width = image.shape[:2]
    side = max(_opening_side(test, width) for test in tests)
    # an opening (erode, dilate) reads its mask up to its side away (an even disc is off-centre)
    reach = moving if side <= 1 else cv2.dilate(moving, np.ones((2 * side + 1,) * 2, np.uint8))
    points = cv2.findNonZero(cv2.inRange(image, *_bgr_box(tests)) & reach)
    masks = [np.zeros(height * width, np.uint8) for _ in tests]
    if points is not None:
        points = points.reshape(-1, 2)
        flat = points[:, 1] * width + points[:, 0]
        hsv = cv2.cvtColor(image.reshape(-1, 3).take(flat, axis=0)[None], cv2.COLOR_BGR2HSV)  # 1 x n pixels
        for mask, test in zip(masks, tests, strict=True):
            mask[flat] = _in_colour_range(hsv, test)[0]
    # an opening only removes pixels, but it may leave some of its reach that did not move
    masks = [mask.reshape(height, width) for mask in masks]
    return [_opened(mask, test, width) & moving if side > 1 else mask
            for mask, test in zip(masks, tests, strict=True)]


@functools.lru_cache(maxsize=8)
def _bgr_box(tests: tuple[BallDetector, ...]) -> tuple[tuple[int, int, int], tuple[int, int, int]]:
    """(low, high) BGR of the smallest box holding every colour that any of the tests' HSV ranges
    (detection._in_colour_range) passes, found by converting all 2^24 colours (50 ms, once): a pixel
    outside it fails every test. The orange ball's loosened test: B 0-135, G 21-212, R 82-255."""
    low, high = np.full(3, 255), np.zeros(3, int)
    green, red = np.meshgrid(np.arange(256, dtype=np.uint8), np.arange(256, dtype=np.uint8), indexing="ij")
    for blue in range(256):
        colours = np.dstack([np.full_like(green, blue), green, red])
        hsv = cv2.cvtColor(colours, cv2.COLOR_BGR2HSV)
        passed = functools.reduce(cv2.bitwise_or, [_in_colour_range(hsv, test) for test in tests]) > 0
        if passed.any():
            found = colours[passed]
            low, high = np.minimum(low, found.min(axis=0)), np.maximum(high, found.max(axis=0))
    return tuple(int(c) for c in low), tuple(int(c) for c in high)


def _hsv_around(image: np.ndarray, hsv: np.ndarray, x: int, y: int, w: int, h: int) -> None:
    """Fills `hsv` with the HSV of `image` on a blob's box (x, y, w, h) and HSV_MARGIN px around it
    (clipped to the image): what the blob's tests read (detection._is_seam 2 px around it,
    detection._skin_without_core 3, detection._weighted_centre 1)."""
    box = np.s_[max(y - HSV_MARGIN, 0):y + h + HSV_MARGIN, max(x - HSV_MARGIN, 0):x + w + HSV_MARGIN]
    hsv[box] = cv2.cvtColor(image[box], cv2.COLOR_BGR2HSV)


def _ranked(hsv, found, reduction: int, detector: BallDetector, settings: TrackSettings) -> list[tuple]:
    """frame_candidates' rows of its blobs (x, y, blob, area, reason, share moving since the previous
    frame): the best candidates_per_frame by _score times that share, and the others ranked out
    ('rank'), centred by detection._weighted_centre; the rest; in full-resolution pixels."""
    offset = (reduction - 1) / 2  # a reduced pixel averages reduction x reduction full ones: their centre
    scored = sorted(((_score(hsv, x, y, blob, detector.centre_channel), x, y, blob, area, reason, fresh)
                     for x, y, blob, area, reason, fresh in found), key=lambda c: (c[5] != "", -c[0] * c[6]))
    rows = []
    for rank, (score, x, y, blob, area, reason, _) in enumerate(scored):
        if not reason and rank >= settings.candidates_per_frame:
            reason = "rank"
        u, v = _weighted_centre(hsv, x, y, blob, detector) if _usable(reason) else \
            (x + (blob.shape[1] - 1) / 2, y + (blob.shape[0] - 1) / 2)
        rows.append((reduction * u + offset, reduction * v + offset, int(round(area * reduction**2)), score,
                     reason))
    return rows


def _usable(reason: str) -> bool:
    """Whether a candidate may be the ball: the best candidates_per_frame ('': linked into tracks) and the
    others passing every test ('rank': taken only where a flight's ends grow into them, `grown`)."""
    return reason in ("", "rank")


def _fresh_share(image: np.ndarray, previous: np.ndarray, x: int, y: int, blob: np.ndarray,
                 threshold: int) -> float:
    """The share of a blob's pixels that differ from the previous frame's by `threshold` (grey level of the
    absolute difference, as Background.moving's): a flying ball leaves its own place each frame, slowly
    moving clothing mostly does not."""
    box = np.s_[y:y + blob.shape[0], x:x + blob.shape[1]]
    difference = cv2.cvtColor(cv2.absdiff(image[box], previous[box]), cv2.COLOR_BGR2GRAY)
    return float(np.count_nonzero((difference >= threshold) & (blob > 0))) / max(np.count_nonzero(blob), 1)


def stream_candidates(frames: Iterable, detector: BallDetector, settings: TrackSettings,
                      scene: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, list, int]:
    """(time_ns (n,), decode_ok (n,), each frame's candidates (frame_candidates), full-resolution width) of
    a stream, decoding one frame at a time at track_reduction of the first image's width. scene: a BGR image
    of the static scene at full resolution (detection.scene_image) that starts the background; None: the
    first frame that decodes."""
    times, decoded, candidates = [], [], []
    reduction, background, shape, width, previous = None, None, None, 0, None
    for frame in frames:
        if reduction is None:
            first, _ = frame.decode(1)
            if first is not None:
                width = first.shape[1]
                reduction = track_reduction(width)
        image, reason = frame.decode(reduction) if reduction else (None, "no image")
        if not reason and image is not None and shape is not None and image.shape != shape:
            reason = f"image {image.shape[1]}x{image.shape[0]}, the stream's is {shape[1]}x{shape[0]}"
        if reason or image is None:
            log.warning("frame at %d ns: %s; skipped", frame.time_ns, reason or "no image")
            found = []
        else:
            if background is None:
                shape = image.shape
                start = image if scene is None else \
                    cv2.resize(scene, shape[1::-1], interpolation=cv2.INTER_AREA)
                background = Background(start, settings.background_s)
            moving = background.moving(image, frame.time_ns, settings.motion_min)
            found = frame_candidates(image, reduction, detector, moving, settings, previous)
            previous = image
        times.append(frame.time_ns)
        decoded.append(not reason and image is not None)
        candidates.append(found)
    return np.asarray(times, np.int64), np.asarray(decoded, bool), candidates, width


@dataclass
class _Track:
    """A hypothesis: its points as (frame, candidate index), their times (s), positions (px) and the
    candidates' ball-likeness (_score)."""

    points: list
    t: list
    uv: list
    likeness: list

    def extended(self, frame: int, index: int, t: float, uv, likeness: float) -> "_Track":
        return _Track(self.points + [(frame, index)], self.t + [t], self.uv + [uv],
                      self.likeness + [likeness])

    def part(self, keep: slice) -> "_Track":
        return _Track(self.points[keep], self.t[keep], self.uv[keep], self.likeness[keep])

    def predict(self, t: float) -> np.ndarray | None:
        """The position at time t from a constant-acceleration fit of the last FIT_POINTS points (constant
        velocity from 2), or None from 1 point."""
        if self._fit is None:
            return None
        dt = t - self.t[-1]
        # np.vander([dt], k)'s row, without its cost: its powers are the products dt * dt
        return np.array([[dt * dt, dt, 1.0] if len(self._fit) == 3 else [dt, 1.0]]) @ self._fit

    @functools.cached_property
    def _fit(self) -> np.ndarray | None:
        """predict's coefficients (highest power first, a column per image axis; time from the last
        point), fitted once: a track is predicted in every frame it lives through without a point (on
        twin.room's camera 2, 3 of 4 predictions), and a track's points never change (extended, part: a
        new track)."""
        n = min(len(self.t), FIT_POINTS)
        if n < 2:
            return None
        times = np.asarray(self.t[-n:]) - self.t[-1]
        design = np.vander(times, 3 if n >= 3 else 2)
        return np.linalg.lstsq(design, np.asarray(self.uv[-n:]), rcond=None)[0]


def _gates(track: _Track, t: float, settings: TrackSettings, scale: float) -> tuple[np.ndarray, float]:
    """(predicted uv or the last point's for a one-point track, gate radius px) of a track at time t."""
    dt = t - track.t[-1]
    predicted = track.predict(t)
    if predicted is None:
        return np.asarray(track.uv[-1]), scale * (settings.gate_px + settings.max_speed_px_s * dt)
    return predicted[0], scale * (settings.gate_px + settings.accel_px_s2 * dt**2 / 2)


def link_tracks(times_ns: np.ndarray, candidates: list[list[tuple]], settings: TrackSettings,
                scale: float) -> list[_Track]:
    """Every track hypothesis of the candidates (those with reason ''), ended: see the module docstring.
    scale: the image's width over REFERENCE_WIDTH."""
    t_s = (times_ns - times_ns[0]) * 1e-9 if len(times_ns) else np.zeros(0)
    live, ended = [], []
    for frame, found in enumerate(candidates):
        t = t_s[frame]
        uv = np.array([c[:2] for c in found if not c[4]], np.float64).reshape(-1, 2)
        likeness = [c[3] for c in found if not c[4]]
        still, extended_by_long = [], set()
        for track in live:
            if t - track.t[-1] > settings.max_gap_s:
                ended.append(track)
                continue
            in_gate = []
            if len(uv):
                centre, gate = _gates(track, t, settings, scale)
                distance = np.hypot(*(uv - centre).T)
                in_gate = [int(i) for i in np.argsort(distance)[:MAX_BRANCHES] if distance[i] <= gate]
            if not in_gate:  # this frame shows no ball of this track (a miss, or it has ended)
                still.append(track)
            for index in in_gate:
                still.append(track.extended(frame, index, t, uv[index], likeness[index]))
                if len(track.t) >= 2:
                    extended_by_long.add(index)
        still += [_Track([(frame, i)], [t], [uv[i]], [likeness[i]]) for i in range(len(uv))
                  if i not in extended_by_long]
        live, dropped = _pruned(still)
        ended += dropped
    return [_trimmed(track) for track in ended + live]


def _pruned(tracks: list[_Track]) -> tuple[list[_Track], list[_Track]]:
    """(live, ended) tracks: of the tracks with the same last 3 points, the one with the most points since
    the latest start among them lives on (a track that jumped a gap loses to the one that followed the
    ball through it), the others end before their first point on it (a flight that ran into a held ball's
    slow track, which has more points since the flight's start, keeps its points up to there: dropping it
    whole lost 15-27 frames of flights into the server's hand on twin.room's camera 0); at most
    MAX_TRACKS live, the longest first."""
    groups = {}
    for track in tracks:
        groups.setdefault(tuple(track.points[-3:]), []).append(track)
    live, ended = [], []
    for group in groups.values():
        if len(group) == 1:  # most tracks (no other shares its last 3 points): nothing to choose
            live.append(group[0])
            continue
        start = max(track.points[0][0] for track in group)
        # points since start: a track's frames increase
        best = max(group, key=lambda tr: (len(tr.points) - bisect.bisect_left(tr.points, start,
                                                                              key=lambda p: p[0]),
                                          len(tr.points)))
        live.append(best)
        shared = set(best.points)
        for track in group:
            if track is not best:
                joined = next(i for i, point in enumerate(track.points) if point in shared)
                if joined:
                    ended.append(track.part(slice(joined)))
    live.sort(key=lambda tr: -len(tr.points))
    return live[:MAX_TRACKS], ended + live[MAX_TRACKS:]


def _trimmed(track: _Track) -> _Track:
    """The track without the runs (points in consecutive frames) of fewer than EDGE_RUN points at its ends
    that a gap parts from the rest: a gate grown over a gap takes whatever lies in it (a track carried over
    a bounce takes the bounce's first point, or a hand beside the ball), where a followed ball has a run."""
    frames = np.array([frame for frame, _ in track.points])
    starts = np.concatenate([[0], np.flatnonzero(np.diff(frames) > 1) + 1, [len(frames)]])
    runs = np.diff(starts)
    first, last = 0, len(runs) - 1
    while first < last and runs[first] < EDGE_RUN:
        first += 1
    while last > first and runs[last] < EDGE_RUN:
        last -= 1
    return track.part(slice(starts[first], starts[last + 1]))


def _fits(track: _Track) -> tuple[float, np.ndarray, np.ndarray]:
    """(RMS residual px, speed px/s at each window's middle, downward acceleration px/s^2 of each window) of
    constant-acceleration fits over each window of FIT_POINTS points of a track (image v grows downwards)."""
    t, uv = np.asarray(track.t), np.asarray(track.uv)
    n = min(len(t), FIT_POINTS)
    squares, speed, fall = [], [], []
    for first in range(0, len(t) - n + 1):
        times, points = t[first:first + n] - t[first], uv[first:first + n]
        design = np.vander(times, 3)
        coefficients = np.linalg.lstsq(design, points, rcond=None)[0]
        squares.append(((points - design @ coefficients) ** 2).sum(axis=1).mean())
        speed.append(np.hypot(*(2 * coefficients[0] * times.mean() + coefficients[1])))
        fall.append(2 * coefficients[0, 1])
    return float(np.sqrt(np.mean(squares))), np.array(speed), np.array(fall)


def judge(track: _Track, settings: TrackSettings, scale: float) -> tuple[str, float]:
    """(reason, score) of a track: reason '' for a ball's flight (score: its candidates' summed ball-likeness
    less its residual in gate units), else why not (module docstring)."""
    if len(track.points) == 1:
        return "lone", 0.0
    if len(track.points) < settings.min_track_points:
        return "short", 0.0
    if np.median(track.likeness) < settings.min_likeness:
        return "colour", 0.0
    residual, speed, fall = _fits(track)
    residual, speed, fall = residual / scale, speed / scale, fall / scale
    if np.median(speed) < settings.min_speed_px_s / 10:
        return "static", 0.0
    falling = (fall >= settings.min_fall_px_s2) & (fall <= settings.max_fall_px_s2)
    held = (speed < settings.min_speed_px_s) & ~falling
    if np.mean(held) > MAX_HELD_SHARE:
        return "slow", 0.0
    if residual > settings.max_residual_px or np.median(fall) < settings.min_fall_px_s2:
        return "non_ballistic", 0.0
    return "", float(np.sum(track.likeness)) - residual / settings.gate_px


def choose_points(tracks: list[tuple[_Track, float]], min_points: int) -> dict[int, int]:
    """frame -> candidate index of the ball: the tracks (track, score) taken best first, each on the frames
    no better track has taken, where it still has min_points there (hypotheses branch and share points, and
    a bounce's or hit's point may end one flight and start the next)."""
    ball = {}
    for track, _ in sorted(tracks, key=lambda ts: -ts[1]):
        free = [(frame, index) for frame, index in track.points if frame not in ball]
        if len(free) >= min_points:
            ball.update(free)
    return ball


def grown(ball: dict[int, int], candidates: list[list[tuple]], times_ns: np.ndarray, settings: TrackSettings,
          scale: float) -> dict[int, int]:
    """choose_points' ball (frame -> candidate index) with each run of EDGE_RUN or more consecutive frames
    grown forwards and backwards, frame by frame, by the constant-acceleration prediction of its end's
    FIT_POINTS points onto the nearest usable candidate within the gate (_gates) of a frame without a
    ball: a flight's first point after a bounce or a hit lies on it but is no point of the track that
    ends there (linking goes forwards only), and a flight's ends of fewer than min_track_points frames
    have no track of their own."""
    ball = dict(ball)
    t_s = (times_ns - times_ns[0]) * 1e-9 if len(times_ns) else np.zeros(0)
    frames = np.array(sorted(ball), np.int64)
    runs = [run for run in np.split(frames, np.flatnonzero(np.diff(frames) > 1) + 1) if len(run) >= EDGE_RUN]
    for run in runs:
        for step in (1, -1):
            end = [int(f) for f in (run if step == 1 else run[::-1])[-FIT_POINTS:]]
            chosen = [candidates[f][ball[f]] for f in end]
            track = _Track([(f, ball[f]) for f in end], [t_s[f] for f in end],
                           [c[:2] for c in chosen], [c[3] for c in chosen])
            frame = end[-1] + step
            while 0 <= frame < len(candidates) and frame not in ball:
                usable = [c for c in candidates[frame] if _usable(c[4])]
                if not usable:
                    break
                centre, gate = _gates(track, t_s[frame], settings, scale)
                distance = np.hypot(*(np.array([c[:2] for c in usable], np.float64) - centre).T)
                index = int(np.argmin(distance))
                if distance[index] > gate:
                    break
                ball[frame] = index
                track = track.extended(frame, index, t_s[frame], usable[index][:2], usable[index][3])
                frame += step
    return ball


def detect_stream(frames: Iterable, detector: BallDetector, settings: TrackSettings,
                  scene: np.ndarray | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(DETECTIONS table, BALL_CANDIDATES table) of a stream of frames (as detection.detect_stream's).
    scene: stream_candidates'."""
    times, decoded, candidates, width = stream_candidates(frames, detector, settings, scene)
    scale = width / REFERENCE_WIDTH if width else 1.0
    tracks = link_tracks(times, candidates, settings, scale)
    judged = [(track, *judge(track, settings, scale)) for track in tracks]
    ball = grown(choose_points([(track, score) for track, reason, score in judged if not reason],
                               settings.min_track_points), candidates, times, settings, scale)
    reasons = {}  # (frame, index) -> the reason of the longest track through it, '' on a valid one
    for track, reason, _ in sorted(judged, key=lambda trs: (not trs[1], len(trs[0].points))):
        for point in track.points:
            reasons[point] = "off_track" if not reason else reason
    return (_detections(times, decoded, candidates, ball),
            _candidate_table(times, candidates, ball, reasons))


def _detections(times, decoded, candidates, ball) -> pd.DataFrame:
    """The DETECTIONS table of the chosen candidates."""
    us, vs, areas = np.full(len(times), np.nan), np.full(len(times), np.nan), np.zeros(len(times), np.int32)
    for frame, index in ball.items():
        us[frame], vs[frame], areas[frame] = candidates[frame][index][:3]
    return pd.DataFrame({"time_ns": times, "u": us, "v": vs, "area_px": areas, "detected": np.isfinite(us),
                         "decode_ok": decoded})


def _candidate_table(times, candidates, ball, reasons) -> pd.DataFrame:
    """The BALL_CANDIDATES table: every candidate, kept or why not."""
    rows = []
    for frame, found in enumerate(candidates):
        ranked = 0
        for u, v, area, score, reason in found:
            if _usable(reason):
                kept = ball.get(frame) == ranked
                reason = "kept" if kept else reasons.get((frame, ranked), reason or "lone")
                ranked += 1
            rows.append((times[frame], u, v, area, score, reason == "kept", reason))
    return candidate_frame(rows)


def candidate_frame(rows) -> pd.DataFrame:
    """A BALL_CANDIDATES table of (time_ns, u, v, area_px, score, kept, reason) rows."""
    table = pd.DataFrame(rows, columns=list(CANDIDATE_COLUMNS))
    return table.astype({"time_ns": np.int64, "u": np.float64, "v": np.float64, "area_px": np.int32,
                         "score": np.float64, "kept": bool, "reason": str})


def colour_candidates(detections: pd.DataFrame) -> pd.DataFrame:
    """The BALL_CANDIDATES table of the colour method: its detections, each kept (score 1)."""
    found = detections[detections["detected"]]
    n = len(found)
    return candidate_frame(zip(found["time_ns"], found["u"], found["v"], found["area_px"], np.ones(n),
                               np.ones(n, bool), ["kept"] * n, strict=True))


def scene_for(frames: Iterable) -> np.ndarray | None:
    """The stream's scene image (detection.scene_image at its sampling) that starts the background."""
    return detection.scene_image(frames, detection.SCENE_EVERY, detection.SCENE_FRAMES)
