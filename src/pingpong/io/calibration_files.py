"""Where a lab's calibration images lie: raw/calibration/{cam}/intrinsics_*.{ext} (the board views) and one
extrinsics shot {stem}.{ext} per camera (table.{ext}: the table mat; extrinsics.{ext}: a board lying at a
known pose), in any image format OpenCV reads.

Light on purpose (no OpenCV): the workflow's rules import it to list the images as inputs, and the
calibration stage finds them with the same functions.
"""

from pathlib import Path

# the suffixes cv2.imread decodes (OpenCV 4 imgcodecs), lower case; matched case-insensitively
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".jpe", ".bmp", ".dib", ".tif", ".tiff", ".webp", ".jp2",
                  ".pbm", ".pgm", ".ppm", ".pxm", ".pnm", ".sr", ".ras", ".exr", ".hdr", ".pic")
VIEWS_STEM = "intrinsics_"
TABLE_SHOT = "table"  # the table's ChArUco mat (perception.calibration_extrinsics: table_mat)
BOARD_SHOT = "extrinsics"  # a board lying at a known pose (perception.calibration_extrinsics: {type: board})
FORMATS = "{" + ",".join(s[1:] for s in IMAGE_SUFFIXES[:7]) + ",...}"  # for messages


class CaptureLayoutError(ValueError):
    pass


def is_image(path: Path) -> bool:
    return path.suffix.lower() in IMAGE_SUFFIXES


def intrinsics_views(folder) -> list[Path]:
    """A camera's board views intrinsics_*.{ext}, sorted by name (any image format, any case)."""
    folder = Path(folder)
    return sorted((p for p in folder.glob(f"{VIEWS_STEM}*") if p.is_file() and is_image(p)), key=str)


def extrinsics_shot(folder, stem: str) -> Path | None:
    """A camera's one extrinsics shot {stem}.{ext}, or None; two formats of it are an error naming them."""
    folder = Path(folder)
    found = sorted((p for p in folder.glob(f"{stem}.*") if p.stem == stem and p.is_file() and is_image(p)),
                   key=str)
    if len(found) > 1:
        raise CaptureLayoutError(f"{folder}: several extrinsics shots {[p.name for p in found]}: keep one "
                                 f"{stem}.{FORMATS}")
    return found[0] if found else None
