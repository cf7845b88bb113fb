"""Import (and export) an existing camera calibration instead of calibrating from images.

Two formats:
- OpenCV FileStorage YAML or JSON (read and written with cv2.FileStorage). Layout written here:
  a top-level sequence `cameras`, each a map with `name`, `image_width`, `image_height`,
  `camera_matrix` (3x3), `distortion_coefficients` (1x5), `R` (3x3) and `tvec` (3x1). Also read:
  top-level maps, one per camera (the key is the name), and the common alternative keys
  K/cameraMatrix, D/dist/dist_coeffs/distCoeffs, rvec (Rodrigues)/rotation_matrix, t/T/translation,
  width/height or image_size/size ([width, height]).
- The Anipose/Pose2Sim TOML: one table per camera with name, size [width, height], matrix,
  distortions (k1 k2 p1 p2 [k3]), rotation (Rodrigues vector), translation; a [metadata] table.

Frames: the extrinsics must be world -> camera in OpenCV's convention (x_cam = R @ x_world + t)
with the world being the table frame (origin at the centre of the table surface, x across the
width, y along the length, z up). Anipose places its world at the first camera or the board it
was calibrated with; move such a calibration into the table frame with `change_world_frame`.
Neither format defines the translation units (Pose2Sim writes metres, Anipose commonly
millimetres), so readers and writers take `units` explicitly; the writers also record them
(top-level `units`, TOML [metadata] units) and the readers refuse a file that states others. The readers
also refuse a rig that the units make implausible (`check_camera_spacing`): metres read as millimetres
put the cameras millimetres apart.

Every value is checked where it enters, and a file that fails is refused with a `CalibrationFileError`
naming the file, the camera, the key and what was expected: numbers finite (never a string, a boolean or an
empty entry read as 0), focal lengths positive, the principal point inside the image, the image size
positive whole pixels, the rotation a rotation, each camera name once. A distortion list one value short
reads as a valid 4-coefficient model, so where no matrix header declares the count (TOML, a plain list),
the file's cameras must agree on it (a one-camera file cannot tell). OpenCV matrices (`!!opencv-matrix`)
are read from their `rows`, `cols`, `dt` and `data` by this module, never by cv2's FileNode.mat(): a
header that does not match its data (`cols: -1`, a huge size) corrupts the heap inside it, and an integer
`dt` saturates values (a focal length of 1681 read as 255 with `dt: u`), so the header is checked and `dt`
must be f or d.
"""

import re
import tomllib
from pathlib import Path

import cv2
import numpy as np
import tomli_w

from pingpong.common.atomic import write_text_atomic
from pingpong.common.camera import Camera
from pingpong.io.guards import check_unique, parse_text

UNITS_M = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
UNIT_NAMES = {"m": "metres", "cm": "centimetres", "mm": "millimetres"}
# Cameras around a table stand 0.3 m (a close pair) to 30 m (the ends of a hall) apart, within 20 m of the
# world origin (the table, a camera or the board the rig was calibrated on). A factor of 10 or 1000 in
# the units lands outside: a calibration in metres read as mm puts the cameras 2 mm apart.
CAMERA_SPACING_M = (0.3, 30.0)
MAX_FROM_ORIGIN_M = 20.0

OPENCV_KEYS = {
    "K": ("camera_matrix", "cameraMatrix", "K"),
    "dist": ("distortion_coefficients", "dist_coeffs", "distCoeffs", "D", "dist"),
    "rotation": ("R", "rotation_matrix", "rvec"),
    "t": ("tvec", "t", "T", "translation"),
}
FIELDS = ("size", "K", "dist", "rotation", "t")  # a camera's values as _camera takes them
ANIPOSE_KEYS = ("size", "matrix", "distortions", "rotation", "translation")  # the FIELDS in TOML
MATRIX_DTYPES = ("f", "d")  # OpenCV's float and double: integer types would saturate or truncate values
MAX_MATRIX_ELEMENTS = 64  # a camera's largest matrix is 3x3 (or 14 distortion coefficients)
QUOTED = re.compile(r""""[^"]*"|'[^']*'""")
BOOLEAN = re.compile(r"(?<![\w.\-])(true|false)(?![\w.\-])")
MAX_IMAGE_SIDE = 65_535  # pixels: the largest side an image format of a camera stream can state


class CalibrationFileError(ValueError):
    """A calibration file that cannot be read as a rig of cameras; the message names the file and where."""


def _unit_scale(units: str) -> float:
    if units not in UNITS_M:
        raise CalibrationFileError(f"units must be one of {sorted(UNITS_M)}, got {units!r}")
    return UNITS_M[units]


def _check_stated_units(stated: str | None, units: str, where: str) -> None:
    if stated is not None and stated != units:
        raise CalibrationFileError(f"{where}: the file states units {stated!r} but {units!r} were asked for")


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _check_leaves(value, where: str, what: str, depth: int) -> None:
    """Refuse anything but numbers in lists no deeper than a matrix's rows (a boolean is not a number)."""
    if isinstance(value, np.ndarray) and value.dtype.kind == "f":
        return
    if isinstance(value, list | tuple) and depth < 2:
        for item in value:
            _check_leaves(item, where, what, depth + 1)
    elif isinstance(value, bool) or not isinstance(value, int | float):
        raise CalibrationFileError(f"{where}: {what}: expected numbers, got {_short(value)}")


def _numbers(value, where: str, what: str) -> np.ndarray:
    """`value` (a number, a list or a list of rows of numbers) as an array of finite floats."""
    _check_leaves(value, where, what, 0)
    try:
        array = np.asarray(value, float)
    except ValueError:  # rows of unequal length
        raise CalibrationFileError(f"{where}: {what}: rows of unequal length in {_short(value)}") from None
    if not np.isfinite(array).all():
        raise CalibrationFileError(f"{where}: {what}: expected finite numbers, got {_short(value)}")
    return array


def _image_size(width, height, where: str) -> tuple[int, int]:
    size = _numbers([width, height], where, "image size").ravel()
    if size.size != 2 or np.any(size != np.round(size)) or not np.all((size >= 1) & (size <= MAX_IMAGE_SIDE)):
        raise CalibrationFileError(f"{where}: image size must be whole pixels from 1 to {MAX_IMAGE_SIDE}, "
                                   f"got {size.tolist()}")
    return int(size[0]), int(size[1])


def _camera_matrix(K, width: int, height: int, where: str) -> np.ndarray:
    """The 3x3 K, checked: positive focal lengths of near square pixels, the principal point in the image."""
    K = _numbers(K, where, "camera matrix").reshape(-1)
    if K.size != 9:
        raise CalibrationFileError(f"{where}: need a 3x3 camera matrix, got {K.size} values")
    K = K.reshape(3, 3)
    (fx, _, cx), (_, fy, cy) = K[0], K[1]
    if K[1, 0] != 0 or K[2].tolist() != [0, 0, 1]:
        raise CalibrationFileError(f"{where}: camera matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]], "
                                   f"got {K.tolist()}")
    if not (fx > 0 and fy > 0 and 0.5 <= fy / fx <= 2):
        raise CalibrationFileError(f"{where}: focal lengths fx {fx:g}, fy {fy:g}: expected positive pixels "
                                   "within a factor of 2 of each other (pixels are near square)")
    if not (0 <= cx <= width and 0 <= cy <= height):
        raise CalibrationFileError(f"{where}: principal point ({cx:g}, {cy:g}) outside the {width}x{height} "
                                   "image")
    return K


def _distortion5(dist, where: str) -> np.ndarray:
    """The 5 coefficients (k1 k2 p1 p2 k3) that Camera models; 4 are padded with k3 = 0."""
    d = _numbers(dist, where, "distortion").ravel()
    if len(d) < 4 or np.any(d[5:] != 0):
        raise CalibrationFileError(f"{where}: distortion needs 4 or 5 coefficients (k1 k2 p1 p2 [k3]), "
                                     f"got {d.tolist()}; the rational, thin-prism and tilted models are "
                                   "not supported")
    return np.pad(d[:5], (0, 5 - min(len(d), 5)))


def _rotation(value, where: str) -> np.ndarray:
    """3x3 rotation from a matrix or a Rodrigues vector, checked to be a rotation."""
    v = _numbers(value, where, "rotation")
    if v.size == 3:
        R = cv2.Rodrigues(v.reshape(3, 1))[0]
    elif v.size == 9:
        R = v.reshape(3, 3)
    else:
        raise CalibrationFileError(f"{where}: rotation must be a 3x3 matrix or a Rodrigues 3-vector, "
                                     f"got {v.size} values")
    if not (np.allclose(R.T @ R, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0):
        raise CalibrationFileError(f"{where}: rotation is not orthonormal with determinant +1")
    return R


def _key(name: str) -> str:
    return f"key {name!r}"


def _camera(name: str, fields: dict[str, tuple[str, object]], scale: float, where: str) -> Camera:
    """A camera of its FIELDS, each (its key as errors name it, its value); errors name camera and key."""
    at = {field: f"{where}: {key}" for field, (key, _) in fields.items()}
    size, K, dist, rotation, t = (fields[field][1] for field in FIELDS)
    width, height = _image_size(*size, at["size"])
    t = _numbers(t, at["t"], "translation").reshape(-1)
    if t.size != 3:
        raise CalibrationFileError(f"{at['t']}: need a 3-vector translation, got {t.size} values")
    return Camera(name=name, K=_camera_matrix(K, width, height, at["K"]), dist=_distortion5(dist, at["dist"]),
                  R=_rotation(rotation, at["rotation"]), t=t * scale, width=width, height=height)


def _rig(path: Path, entries: list[tuple[str, dict, str]], scale: float, units: str) -> list[Camera]:
    """The cameras of a file's (name, fields, place) entries, checked as one rig: each name once, the
    distortions' lengths agreeing (`_check_distortion_lengths`), the spacing plausible."""
    check_unique([name for name, _, _ in entries], [place for *_, place in entries], CalibrationFileError,
                 str(path), "cameras")
    cameras = [_camera(name, fields, scale, f"{path}: {place}") for name, fields, place in entries]
    _check_distortion_lengths(path, entries)
    check_camera_spacing(cameras, units, str(path))
    return cameras


def _check_distortion_lengths(path: Path, entries: list[tuple[str, dict, str]]) -> None:
    """Distortions one value short (k1 k2 p1 p2 k3 with one lost) read as a valid 4-coefficient model: where
    no matrix header declares their count (a TOML or plain list), the file's cameras must agree on it."""
    lengths = [(np.size(fields["dist"][1]), place, fields["dist"][0]) for _, fields, place in entries
               if not isinstance(fields["dist"][1], np.ndarray)]
    if len({n for n, _, _ in lengths}) > 1:
        (short, place, key), (most, other, _) = min(lengths), max(lengths)
        raise CalibrationFileError(f"{path}: {place}: {key}: {short} distortion coefficients where {other} "
                                   f"has {most}; expected {most} for every camera of the file (a value lost? "
                                   "pad a camera calibrated with fewer with zeros)")


def check_camera_spacing(cameras: list[Camera], units: str, where: str) -> None:
    """Refuse camera centres closer or farther apart, or farther from the origin, than a lab's rig can be,
    suggesting the units that would make them plausible."""
    centres = np.array([c.center for c in cameras])
    names = [c.name for c in cameras]
    problem = _spacing_problem(names, centres)
    if problem is None:
        return
    rescaled = {u: centres * UNITS_M[u] / UNITS_M[units] for u in UNITS_M if u != units}
    fits = [u for u, c in rescaled.items() if _spacing_problem(names, c) is None]
    advice = (f"is units {units!r} right for a file in {UNIT_NAMES[fits[0]]}?" if fits
              else "check the file's extrinsics and its units")
    raise CalibrationFileError(f"{where}: {problem} with units {units!r}: {advice}")


def _spacing_problem(names: list[str], centres: np.ndarray) -> str | None:
    lo, hi = CAMERA_SPACING_M
    far = np.linalg.norm(centres, axis=1)
    if far.max() > MAX_FROM_ORIGIN_M:
        c = int(far.argmax())
        return (f"camera {names[c]} is {_length(far[c])} from the world origin (expected within "
                f"{MAX_FROM_ORIGIN_M:g} m)")
    for a in range(len(centres)):
        for b in range(a + 1, len(centres)):
            d = float(np.linalg.norm(centres[a] - centres[b]))
            if not lo <= d <= hi:
                return f"cameras {names[a]} and {names[b]} {_length(d)} apart (expected {lo:g} to {hi:g} m)"
    return None


def _length(metres: float) -> str:
    if metres < 0.1:
        return f"{1e3 * metres:.3g} mm"
    return f"{metres:.3g} m" if metres < 100 else f"{metres:.0f} m"


def change_world_frame(cameras: list[Camera], T_old_from_new: np.ndarray) -> list[Camera]:
    """Cameras with extrinsics re-expressed in a new world frame (e.g. old = Anipose's, new = table)."""
    R_on, t_on = T_old_from_new[:3, :3], T_old_from_new[:3, 3]
    return [Camera(c.name, c.K, c.dist, c.R @ R_on, c.R @ t_on + c.t, c.width, c.height) for c in cameras]


# --- Anipose / Pose2Sim TOML -----------------------------------------------------------------------

def read_anipose_toml(path: str | Path, *, units: str) -> list[Camera]:
    """Cameras (in file order) from an Anipose/Pose2Sim calibration TOML whose translations are in `units`."""
    path = Path(path)
    scale = _unit_scale(units)
    doc = parse_text(path, tomllib.loads, CalibrationFileError, "valid TOML")
    metadata = doc.get("metadata", {})
    if not isinstance(metadata, dict):
        raise CalibrationFileError(f"{path}: [metadata]: expected a table, got {_short(metadata)}")
    _check_stated_units(metadata.get("units"), units, f"{path}: [metadata]")
    entries = []
    for section, cam in doc.items():
        if section == "metadata":
            continue
        where = f"{path}: [{section}]"
        if not isinstance(cam, dict):
            raise CalibrationFileError(f"{where}: expected a camera table")
        missing = [k for k in ANIPOSE_KEYS if k not in cam]
        if missing:
            raise CalibrationFileError(f"{where}: missing key(s) {missing}")
        if cam.get("fisheye", False) is not False:
            raise CalibrationFileError(f"{where}: fisheye cameras are not supported")
        if not isinstance(cam["size"], list) or len(cam["size"]) != 2:
            raise CalibrationFileError(f"{where}: key 'size': must be [width, height], got "
                                       f"{_short(cam['size'])}")
        name = cam.get("name", section)
        if not isinstance(name, str):
            raise CalibrationFileError(f"{where}: name must be a string, got {_short(name)}")
        fields = {field: (_key(k), cam[k]) for field, k in zip(FIELDS, ANIPOSE_KEYS, strict=True)}
        entries.append((name, fields, f"[{section}]"))
    if not entries:
        raise CalibrationFileError(f"{path}: no camera tables")
    return _rig(path, entries, scale, units)


def export_anipose_toml(cameras: list[Camera], path: str | Path, *, units: str = "m") -> None:
    """Write cameras as an Anipose/Pose2Sim calibration TOML ([cam_0], ...), translations in `units`."""
    scale = _unit_scale(units)
    doc = {
        f"cam_{i}": {
            "name": cam.name,
            "size": [cam.width, cam.height],
            "matrix": cam.K.tolist(),
            "distortions": cam.dist.tolist(),
            "rotation": cv2.Rodrigues(cam.R)[0].ravel().tolist(),
            "translation": (cam.t / scale).tolist(),
        }
        for i, cam in enumerate(cameras)
    }
    doc["metadata"] = {"adjusted": False, "error": 0.0, "units": units}
    write_text_atomic(path, tomli_w.dumps(doc))


# --- OpenCV FileStorage YAML / JSON ----------------------------------------------------------------

def _is_matrix(node: "cv2.FileNode") -> bool:
    """Whether a node is an !!opencv-matrix (JSON: a map with type_id); FileNode.mat() throws otherwise."""
    return node.isMap() and "data" in node.keys()


def _node_value(node: "cv2.FileNode", depth: int = 0):
    """A FileStorage node as a number, string, list (no deeper than a matrix's rows) or numpy array (for
    !!opencv-matrix); an empty entry is refused, not read as 0."""
    if node.isMap():
        return _matrix(node)
    if node.isSeq() and depth < 2:
        return [_node_value(node.at(i), depth + 1) for i in range(node.size())]
    if node.isString():
        return node.string()
    if node.isInt() or node.isReal():
        return node.real()
    raise CalibrationFileError("lists nested deeper than a matrix's rows" if node.isSeq()
                               else "an empty entry where a number, a list or a matrix was expected")


def _matrix(node: "cv2.FileNode") -> np.ndarray:
    """An !!opencv-matrix from its rows, cols, dt and data, each checked (never FileNode.mat(): module
    docstring)."""
    keys = set(node.keys())
    if not {"rows", "cols", "dt", "data"} <= keys:
        raise CalibrationFileError(f"a map with keys {sorted(keys)} where a matrix (rows, cols, dt, data) or "
                                   "a list was expected")
    rows, cols, dt, data = (node.getNode(k) for k in ("rows", "cols", "dt", "data"))
    shape = (int(rows.real()), int(cols.real())) if rows.isInt() and cols.isInt() else None
    if shape is None or min(shape) < 1 or shape[0] * shape[1] > MAX_MATRIX_ELEMENTS:
        raise CalibrationFileError(f"matrix rows {_short(_raw(rows))}, cols {_short(_raw(cols))}: expected "
                                   f"whole numbers from 1 with at most {MAX_MATRIX_ELEMENTS} elements")
    if not dt.isString() or dt.string() not in MATRIX_DTYPES:
        raise CalibrationFileError(f"matrix dt {_short(_raw(dt))}: expected one of {list(MATRIX_DTYPES)} "
                                   "(an integer type would saturate or truncate the values)")
    if not data.isSeq() or data.size() != shape[0] * shape[1]:
        raise CalibrationFileError(f"matrix of {shape[0]}x{shape[1]}: expected a list of "
                                   f"{shape[0] * shape[1]} numbers as data, got "
                                   f"{data.size() if data.isSeq() else 'no list'}")
    values = [_node_value(data.at(i), 2) for i in range(data.size())]
    if any(isinstance(v, str) for v in values):
        raise CalibrationFileError(f"matrix data: expected numbers, got {_short(values)}")
    array = np.array(values, np.float32 if dt.string() == "f" else float).reshape(shape)
    return array.astype(float)


def _raw(node: "cv2.FileNode"):
    """A scalar node's value for a message (a string, a number, or what kind of node it is)."""
    if node.isString():
        return node.string()
    if node.isInt() or node.isReal():
        return node.real()
    return "a list" if node.isSeq() else "a map" if node.isMap() else "nothing"


def _opencv_camera(node: "cv2.FileNode", default_name: str, where: str) -> tuple[str, dict]:
    """(name, FIELDS) of a camera map, each field (the key it was read from, its value)."""
    if not node.isMap():
        raise CalibrationFileError(f"{where}: expected a camera map, got {_short(_raw(node))}")
    keys = set(node.keys())

    def get(field: str, names: tuple[str, ...]) -> tuple[str, object]:
        found = [n for n in names if n in keys]
        if not found:
            raise CalibrationFileError(f"{where}: missing {field!r} (one of the keys {list(names)})")
        try:
            return _key(found[0]), _node_value(node.getNode(found[0]))
        except ValueError as err:
            raise CalibrationFileError(f"{where}: {_key(found[0])}: {err}") from None

    if {"image_width", "image_height"} <= keys or {"width", "height"} <= keys:
        w_key, h_key = ("image_width", "image_height") if "image_width" in keys else ("width", "height")
        size = f"keys {w_key!r}, {h_key!r}", (get("width", (w_key,))[1], get("height", (h_key,))[1])
    else:
        key, value = get("image size", ("image_size", "size"))
        values = _numbers(value, f"{where}: {key}", "image size").ravel()
        if values.size != 2:
            raise CalibrationFileError(f"{where}: {key}: image size must be [width, height], got "
                                       f"{values.tolist()}")
        size = key, values
    if "name" in keys and not node.getNode("name").isString():
        raise CalibrationFileError(f"{where}: name must be a string, got "
                                   f"{_short(_raw(node.getNode('name')))}")
    name = node.getNode("name").string() if "name" in keys else default_name
    return name, {"size": size, **{field: get(field, names) for field, names in OPENCV_KEYS.items()}}


def read_opencv_calibration(path: str | Path, *, units: str) -> list[Camera]:
    """Cameras from an OpenCV FileStorage YAML/JSON calibration whose translations are in `units`."""
    path = Path(path)
    scale = _unit_scale(units)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: calibration file not found")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as err:
        raise CalibrationFileError(f"{path}: not a readable OpenCV YAML/JSON file "
                                   f"({err.__cause__ or err})") from None
    try:
        _refuse_booleans(path)
        entries = _opencv_cameras(fs.root(), path, units)
    except UnicodeDecodeError as err:  # a key or string that is not UTF-8
        raise CalibrationFileError(f"{path}: not a readable OpenCV YAML/JSON file ({err})") from None
    finally:
        fs.release()
    return _rig(path, entries, scale, units)


def _refuse_booleans(path: Path) -> None:
    """FileStorage reads a bare `true` or `false` as the integer 1 or 0, and its nodes cannot tell them
    from numbers: a calibration holds none, so one in the text (outside quotes and comments) is refused."""
    for number, line in enumerate(path.read_bytes().decode("utf-8", "replace").splitlines(), 1):
        bare = QUOTED.sub('""', line).split("#")[0]
        found = BOOLEAN.search(bare)
        if found:
            raise CalibrationFileError(f"{path}: line {number}: {found.group()!r} where a number or a string "
                                       "was expected (OpenCV would read it as "
                                       f"{int(found.group() == 'true')})")


def _opencv_cameras(root: "cv2.FileNode", path: Path, units: str) -> list[tuple[str, dict, str]]:
    """(name, FIELDS, place) of each camera of the file (`_rig` makes them cameras)."""
    if not root.isMap():
        raise CalibrationFileError(f"{path}: expected a map at the top level")
    if "units" in root.keys():
        _check_stated_units(_raw(root.getNode("units")), units, f"{path}: units")
    if "cameras" in root.keys():
        seq = root.getNode("cameras")
        if not seq.isSeq():
            raise CalibrationFileError(f"{path}: 'cameras' must be a sequence of camera maps")
        nodes = [(f"cam{i}", seq.at(i), f"cameras[{i}]") for i in range(seq.size())]
    elif set(OPENCV_KEYS["K"]) & set(root.keys()):  # a single camera at the top level
        nodes = [(path.stem, root, "top level")]
    else:  # one map per camera, its key the name (FileStorage lists a repeated key twice)
        nodes = [(key, root.getNode(key), key) for key in root.keys()
                 if root.getNode(key).isMap() and not _is_matrix(root.getNode(key))]
    if not nodes:
        raise CalibrationFileError(f"{path}: no cameras (expected a 'cameras' sequence or one map per "
                                   "camera)")
    return [(*_opencv_camera(node, name, f"{path}: {place}"), place) for name, node, place in nodes]


def export_opencv_yaml(cameras: list[Camera], path: str | Path, *, units: str = "m") -> None:
    """Write cameras in this module's OpenCV FileStorage layout; JSON if path ends in .json, else YAML."""
    scale = _unit_scale(units)
    is_json = Path(path).suffix.lower() == ".json"
    fmt = cv2.FILE_STORAGE_FORMAT_JSON if is_json else cv2.FILE_STORAGE_FORMAT_YAML
    # written in memory, then renamed into place: FileStorage would pick the format from the temp name
    fs = cv2.FileStorage("", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY | fmt)
    fs.write("units", units)
    fs.startWriteStruct("cameras", cv2.FileNode_SEQ)
    for cam in cameras:
        fs.startWriteStruct("", cv2.FileNode_MAP)
        fs.write("name", cam.name)
        fs.write("image_width", cam.width)
        fs.write("image_height", cam.height)
        fs.write("camera_matrix", cam.K)
        fs.write("distortion_coefficients", cam.dist.reshape(1, -1))
        fs.write("R", cam.R)
        fs.write("tvec", (cam.t / scale).reshape(3, 1))
        fs.endWriteStruct()
    fs.endWriteStruct()
    write_text_atomic(path, fs.releaseAndGetString())
