"""Camera calibration readers: Middlebury/ETH3D ``calib.txt``, KITTI ``P_rect``, OpenCV ``Q``.

All readers return a :class:`~dispeval_ros.core.camera.Camera` with ``f`` in pixels, the
baseline in metres (Middlebury and ETH3D give millimetres; they are converted) and ``doffs``
in pixels in the Middlebury convention ``Z = f·B / (d + doffs)``, ``doffs = cx_right −
cx_left``. Every problem raises :class:`~dispeval_ros.errors.CalibrationError` with a one-line
message naming the file and the field.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from dispeval_ros.core.camera import Camera
from dispeval_ros.errors import CalibrationError
from dispeval_ros.io.files import PathLike

_MM_PER_M = 1000.0

# A label such as "P_rect_02:" or "calib_time:" starting a KITTI field.
_KITTI_LABEL = re.compile(r"(?m)^[ \t]*([A-Za-z_][A-Za-z0-9_]*)[ \t]*:")
_MIDDLEBURY_LINE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=(.*)$")
# Pairs of (left, right) KITTI projection matrices, in order of preference.
_KITTI_PAIRS = (("P_rect_02", "P_rect_03"), ("P2", "P3"))


def _shown(text: str, limit: int = 50) -> str:
    text = text.strip()
    shown = repr(text)
    return shown if len(shown) <= limit else shown[: limit - 3] + "..."


def _number(text: str, path: Path, field: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise CalibrationError(f"{path}: {field} must be a finite number, got {_shown(text)}")
    return value


def _numbers(text: str, path: Path, field: str, count: int, expected: str) -> list[float]:
    tokens = [token for token in re.split(r"[\s,;\[\]]+", text) if token]
    if len(tokens) != count:
        raise CalibrationError(
            f"{path}: {field} must be {count} numbers {expected}, got {len(tokens)}: {_shown(text)}"
        )
    return [_number(token, path, field) for token in tokens]


def _camera(path: Path, f: float, baseline: float, doffs: float, f_field: str) -> Camera:
    if f <= 0:
        raise CalibrationError(f"{path}: {f_field} focal length must be > 0 px, got {f:g}")
    if baseline <= 0:
        raise CalibrationError(f"{path}: baseline must be > 0, got {baseline:g}")
    return Camera(f=f, baseline=baseline, doffs=doffs)


# ------------------------------------------------------------------------ Middlebury / ETH3D


def _parse_middlebury(text: str, path: Path) -> Camera:
    fields: dict[str, str] = {}
    for line in text.splitlines():
        match = _MIDDLEBURY_LINE.match(line)
        if match:
            fields[match.group(1).lower()] = match.group(2).strip()
    for required in ("cam0", "baseline"):
        if required not in fields:
            raise CalibrationError(f"{path}: missing field '{required}' (Middlebury calib.txt)")
    matrix = "'[f 0 cx; 0 f cy; 0 0 1]'"
    cam0 = _numbers(fields["cam0"], path, "cam0", 9, matrix)
    cam1 = _numbers(fields["cam1"], path, "cam1", 9, matrix) if "cam1" in fields else None
    for name, value in (("width", "width"), ("height", "height"), ("ndisp", "ndisp")):
        if name in fields:
            number = _number(fields[name], path, value)
            if number <= 0:
                raise CalibrationError(f"{path}: {name} must be > 0, got {fields[name]}")
    for name in ("vmin", "vmax", "isint", "dyavg", "dymax"):
        if name in fields:
            _number(fields[name], path, name)
    f = cam0[0]
    if "doffs" in fields:
        doffs = _number(fields["doffs"], path, "doffs")
    elif cam1 is not None:
        doffs = cam1[2] - cam0[2]
    else:
        raise CalibrationError(f"{path}: missing field 'doffs' (and no 'cam1' to derive it)")
    baseline_mm = _number(fields["baseline"], path, "baseline")
    return _camera(path, f, baseline_mm / _MM_PER_M, doffs, "cam0")


# ------------------------------------------------------------------------------------ KITTI


def _kitti_fields(text: str) -> dict[str, str]:
    """Map every ``label:`` to the text up to the next label (values may span lines)."""
    matches = list(_KITTI_LABEL.finditer(text))
    fields: dict[str, str] = {}
    for index, match in enumerate(matches):
        end = matches[index + 1].start() if index + 1 < len(matches) else len(text)
        fields.setdefault(match.group(1), text[match.end() : end])
    return fields


def _parse_kitti(text: str, path: Path) -> Camera:
    fields = _kitti_fields(text)
    left_name, right_name = next(
        (pair for pair in _KITTI_PAIRS if pair[0] in fields or pair[1] in fields),
        _KITTI_PAIRS[0],
    )
    for name in (left_name, right_name):
        if name not in fields:
            raise CalibrationError(f"{path}: missing field '{name}' (KITTI calibration)")
    rows = "(3×4 projection matrix)"
    left = _numbers(fields[left_name], path, left_name, 12, rows)
    right = _numbers(fields[right_name], path, right_name, 12, rows)
    f = left[0]
    if f <= 0:
        raise CalibrationError(f"{path}: {left_name}[0,0] focal length must be > 0, got {f:g}")
    baseline = (left[3] - right[3]) / f
    if baseline <= 0:
        raise CalibrationError(
            f"{path}: baseline ({left_name}[0,3] − {right_name}[0,3]) / f must be > 0, "
            f"got {baseline:g} m (are the left and right matrices swapped?)"
        )
    doffs = right[2] - left[2]
    return _camera(path, f, baseline, doffs, f"{left_name}[0,0]")


# ------------------------------------------------------------------------------------ Q.dat


def _parse_q(text: str, path: Path) -> Camera:
    q = _numbers(text, path, "Q", 16, "(4×4 reprojection matrix)")
    f = abs(q[2 * 4 + 3])
    inverse_baseline = q[3 * 4 + 2]
    if f == 0:
        raise CalibrationError(f"{path}: Q[2,3] (focal length) must be non-zero, got 0")
    if inverse_baseline == 0:
        raise CalibrationError(f"{path}: Q[3,2] (−1/Tx, the inverse baseline) must be non-zero")
    # OpenCV: Q[3,2] = −1/Tx, Q[3,3] = (cx − cx')/Tx, so W = (d + cx' − cx)/B and the
    # Middlebury doffs = cx' − cx = Q[3,3]/Q[3,2] (also when the signs are flipped).
    baseline = 1.0 / abs(inverse_baseline)
    doffs = q[3 * 4 + 3] / inverse_baseline
    return _camera(path, f, baseline, doffs, "Q[2,3]")


# -------------------------------------------------------------------------------- read_calib


def _looks_like_q(text: str) -> bool:
    """Only numbers (a matrix): parsed as Q, whose reader checks there are 16."""
    return not re.search(r"[A-DF-Za-df-z_:=]", text)


def read_calib(path: PathLike) -> Camera:
    """Read a camera from a calibration file, detecting its format from the content.

    Formats: Middlebury/MiddEval3/ETH3D ``calib.txt`` (``cam0=[...]``, ``doffs``,
    ``baseline`` in mm → m; ``doffs`` defaults to ``cam1.cx − cam0.cx``); KITTI
    ``P_rect_02:``/``P_rect_03:`` or ``P2:``/``P3:`` (3×4 rows on one or several lines;
    ``f = P2[0,0]``, ``B = (P2[0,3] − P3[0,3]) / f``, ``doffs = P3[0,2] − P2[0,2]``); an OpenCV
    4×4 reprojection matrix ``Q`` (``f = |Q[2,3]|``, ``B = 1/|Q[3,2]|``, ``doffs =
    Q[3,3]/Q[3,2]``).
    """
    file = Path(path)
    try:
        raw = file.read_bytes()
    except FileNotFoundError:
        raise CalibrationError(f"{file}: calibration file not found") from None
    except IsADirectoryError:
        raise CalibrationError(f"{file}: expected a calibration file, got a directory") from None
    except OSError as exc:
        raise CalibrationError(
            f"{file}: cannot read calibration file ({exc.strerror or exc})"
        ) from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise CalibrationError(
            f"{file}: calibration file must be text, found binary data"
        ) from None
    if not text.strip():
        raise CalibrationError(f"{file}: calibration file is empty")
    if re.search(r"(?mi)^\s*cam0\s*=", text):
        return _parse_middlebury(text, file)
    labels = set(_kitti_fields(text))
    if any(left in labels or right in labels for left, right in _KITTI_PAIRS):
        return _parse_kitti(text, file)
    if _looks_like_q(text):
        return _parse_q(text, file)
    first = text.strip().splitlines()[0]
    raise CalibrationError(
        f"{file}: unknown calibration format: expected Middlebury 'cam0=[...]', KITTI "
        f"'P_rect_02:'/'P2:' or a 4×4 Q matrix, found {_shown(first)}"
    )
