"""A lab's ball colour from a few of its frames: the OpenCV HSV range to put in config perception.ball.hsv.

    python -m pingpong.perception.ball_colour FRAME.jpg... --labels LABEL.txt...
    python -m pingpong.perception.ball_colour FRAME.jpg --box 604 576 41 21

Each frame's ball box comes from its YOLO label file (`class cx cy w h`, normalised by the image's width
and height; one box per file) or from --box (centre x, y, width, height in px, once per frame). The box may
hold the ball's blur streak: the pixels of the ellipse inscribed in its middle half (the ball's core, clear
of the background around it) are pooled over all frames, and the range printed is their 2nd to 98th
percentile per channel. Hue is not wrapped: a red ball (hue on both sides of 0) needs a range by hand.
"""

import argparse
from pathlib import Path

import cv2
import numpy as np

PERCENTILES = (2, 98)  # of the pooled core pixels: the range, a few JPEG outliers left out
CORE = 0.5  # of the box's width and height: the ellipse whose pixels are the ball's


def read_yolo_box(path: Path, width: int, height: int) -> tuple[float, float, float, float]:
    """(cx, cy, w, h) px of the one box of a YOLO label file for an image width x height px."""
    _, cx, cy, w, h = map(float, Path(path).read_text().split()[:5])
    return cx * width, cy * height, w * width, h * height


def core_pixels(image_bgr: np.ndarray, box) -> np.ndarray:
    """(N, 3) HSV of the pixels in the ellipse of CORE of the box (cx, cy, w, h px) about its centre."""
    cx, cy, w, h = box
    mask = np.zeros(image_bgr.shape[:2], np.uint8)
    axes = (max(1, round(CORE * w / 2)), max(1, round(CORE * h / 2)))
    cv2.ellipse(mask, (round(cx), round(cy)), axes, 0, 0, 360, 1, -1)
    return cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV)[mask > 0]


def hsv_range(pixels: np.ndarray) -> dict:
    """{hue: [lo, hi], saturation: [lo, hi], value: [lo, hi]} of the pooled core pixels (N, 3)."""
    low, high = np.percentile(pixels, PERCENTILES, axis=0)
    return {name: [int(np.floor(low[k])), int(np.ceil(high[k]))]
            for k, name in enumerate(("hue", "saturation", "value"))}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("images", nargs="+", type=Path)
    ap.add_argument("--labels", nargs="+", type=Path, help="a YOLO label file per image, in the same order")
    ap.add_argument("--box", nargs=4, type=float, action="append", metavar=("CX", "CY", "W", "H"),
                    help="px, once per image, in the same order")
    a = ap.parse_args(argv)
    boxes = a.labels or a.box
    if boxes is None or len(boxes) != len(a.images):
        ap.error("give one --labels file or one --box per image")
    pixels = []
    for path, box in zip(a.images, boxes, strict=True):
        image = cv2.imread(str(path))
        if image is None:
            ap.error(f"{path}: not an image OpenCV reads")
        height, width = image.shape[:2]
        pixels.append(core_pixels(image, read_yolo_box(box, width, height) if a.labels else box))
    r = hsv_range(np.concatenate(pixels))
    print(f"# from {len(a.images)} frames, {sum(len(p) for p in pixels)} px\nperception:\n  ball:\n"
          f"    hsv: {{hue: {r['hue']}, saturation: {r['saturation']}, value: {r['value']}}}")


if __name__ == "__main__":
    main()
