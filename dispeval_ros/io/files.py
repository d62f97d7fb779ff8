"""Readers and writers of disparity maps and masks.

Values are returned as the source encodes them, after applying the source's scale: ``inf``
stays ``inf`` and ``0`` stays ``0``. Deciding which points are valid (finite and > 0) is the
core's job, not this module's.

Every problem with a file raises :class:`~dispeval_ros.errors.InputError` with a one-line
message naming the file, what was expected and what came.
"""

from __future__ import annotations

import io
import math
import os
import zipfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO, TypeAlias

import cv2
import numpy as np

from dispeval_ros.errors import InputError

PathLike: TypeAlias = str | os.PathLike[str]

#: Extensions :func:`read_disparity` decodes.
DISPARITY_EXTENSIONS = (".pfm", ".npy", ".npz", ".png", ".pgm", ".ppm")
#: Extensions :func:`read_mask` decodes.
MASK_EXTENSIONS = (".png", ".pgm", ".ppm", ".pbm", ".bmp", ".npy", ".npz")
_IMAGE_EXTENSIONS = (".png", ".pgm", ".ppm", ".pbm", ".bmp")

#: Scale of 16-bit disparity PNGs (KITTI): disparity = value / 256, 0 = no GT.
PNG16_SCALE = 256.0
_PNG16_MAX = 65535

_WHITESPACE = b" \t\r\n\v\f"
_PFM_HEADER_LIMIT = 4096


def _one_line(text: object, limit: int = 60) -> str:
    """Quote a value for a one-line message (newlines escaped, long values cut)."""
    shown = repr(text)
    return shown if len(shown) <= limit else shown[: limit - 3] + "..."


def _read_bytes(path: Path, what: str) -> bytes:
    """Read a whole file, turning OS errors and empty files into InputError."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: {what} file not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: expected a {what} file, got a directory") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read {what} file ({exc.strerror or exc})") from None
    if not data:
        raise InputError(f"{path}: {what} file is empty (0 bytes)")
    return data


# --------------------------------------------------------------------------------------- PFM


def _pfm_tokens(data: bytes, path: Path) -> tuple[list[bytes], int]:
    """Split the PFM header into its 4 tokens; return them and the offset after the last.

    Tokens are separated by any whitespace; ``#`` starts a comment running to the end of the
    line (allowed between tokens, as in PNM headers).
    """
    tokens: list[bytes] = []
    pos = 0
    end = min(len(data), _PFM_HEADER_LIMIT)
    while len(tokens) < 4:
        while pos < end and data[pos] in _WHITESPACE:
            pos += 1
        if pos < end and data[pos] == ord("#"):
            while pos < end and data[pos] not in b"\r\n":
                pos += 1
            continue
        if pos >= end:
            found = b" ".join(tokens).decode("latin-1")
            raise InputError(
                f"{path}: PFM header incomplete: expected 'Pf|PF width height scale', "
                f"found {_one_line(found)}"
            )
        start = pos
        while pos < end and data[pos] not in _WHITESPACE and data[pos] != ord("#"):
            pos += 1
        tokens.append(data[start:pos])
    return tokens, pos


def _is_filler(segment: bytes) -> bool:
    """Whether ``segment`` is only whitespace and ``#`` comments ending in a line break."""
    pos = 0
    while pos < len(segment):
        if segment[pos] in _WHITESPACE:
            pos += 1
        elif segment[pos] == ord("#"):
            line_end = segment.find(b"\n", pos)
            if line_end < 0:
                return False
            pos = line_end + 1
        else:
            return False
    return True


def _parse_pfm_header(data: bytes, path: Path) -> tuple[int, int, int, str, int]:
    """Return ``(height, width, channels, byte order, offset of the data)``."""
    if data[:2] not in (b"Pf", b"PF"):
        raise InputError(
            f"{path}: not a PFM file: expected the magic 'Pf' or 'PF', "
            f"found {_one_line(data[:2].decode('latin-1'))}"
        )
    tokens, pos = _pfm_tokens(data, path)
    magic, width_token, height_token, scale_token = tokens
    if magic not in (b"Pf", b"PF"):
        raise InputError(
            f"{path}: PFM magic must be followed by whitespace, "
            f"found {_one_line(magic.decode('latin-1'))}"
        )
    channels = 1 if magic == b"Pf" else 3
    try:
        width, height = int(width_token), int(height_token)
    except ValueError:
        dims = (width_token + b" " + height_token).decode("latin-1")
        raise InputError(
            f"{path}: PFM size must be two integers 'width height', found {_one_line(dims)}"
        ) from None
    if width <= 0 or height <= 0:
        raise InputError(f"{path}: PFM size must be positive, found {width}x{height}")
    try:
        scale = float(scale_token)
    except ValueError:
        scale = math.nan
    if not math.isfinite(scale) or scale == 0:
        raise InputError(
            f"{path}: PFM scale must be a non-zero number (its sign gives the byte order), "
            f"found {_one_line(scale_token.decode('latin-1'))}"
        )
    order = "<" if scale < 0 else ">"

    expected = width * height * channels * 4
    # The header ends with one whitespace character after the scale. Writers that put
    # "\r\n", " \n" or a comment there are accepted too: if the bytes between the scale and
    # (end of file - data size) are only whitespace and comments, the data follows them.
    if pos >= len(data):
        available = 0
    else:
        pos += 1
        available = len(data) - pos
        if available > expected:
            start = len(data) - expected
            if _is_filler(data[pos - 1 : start]):
                pos = start
            available = len(data) - pos
    if available < expected:
        raise InputError(
            f"{path}: PFM data truncated: expected {expected} bytes for {width}x{height}x"
            f"{channels} float32, found {available}"
        )
    return height, width, channels, order, pos


def read_pfm(path: PathLike) -> np.ndarray:
    """Read a PFM file into a float32 array (H×W for ``Pf``, H×W×3 for ``PF``).

    The sign of the scale field gives the byte order (negative = little-endian); its
    magnitude is ignored (MiddEval3 writes 1/255 there, which is *not* a factor to apply).
    Rows are stored bottom-to-top and returned top-down. The result is a C-contiguous,
    native-endian array that owns its data.
    """
    file = Path(path)
    data = _read_bytes(file, "PFM")
    height, width, channels, order, offset = _parse_pfm_header(data, file)
    count = height * width * channels
    values = np.frombuffer(data, dtype=np.dtype(f"{order}f4"), count=count, offset=offset)
    shape = (height, width) if channels == 1 else (height, width, 3)
    image = values.reshape(shape)[::-1]
    return np.ascontiguousarray(image, dtype=np.float32)


def write_pfm(path: PathLike, array: np.ndarray) -> None:
    """Write an H×W or H×W×3 array as a little-endian, bottom-to-top float32 PFM."""
    file = Path(path)
    values = np.asarray(array)
    if values.ndim == 2:
        magic = b"Pf"
    elif values.ndim == 3 and values.shape[2] == 3:
        magic = b"PF"
    else:
        raise InputError(
            f"{file}: PFM needs an H×W or H×W×3 array, got shape {tuple(values.shape)}"
        )
    if values.shape[0] == 0 or values.shape[1] == 0:
        raise InputError(f"{file}: PFM needs a non-empty array, got shape {values.shape}")
    if not np.issubdtype(values.dtype, np.number) or np.iscomplexobj(values):
        raise InputError(f"{file}: PFM needs real numbers, got dtype {values.dtype}")
    height, width = values.shape[:2]
    body = np.ascontiguousarray(values[::-1], dtype="<f4").tobytes()
    header = magic + f"\n{width} {height}\n-1\n".encode("ascii")
    try:
        file.write_bytes(header + body)
    except OSError as exc:
        raise InputError(f"{file}: cannot write PFM file ({exc.strerror or exc})") from None


# ------------------------------------------------------------------------------ image decode


@contextmanager
def quiet_opencv() -> Iterator[None]:
    """OpenCV's own log lines off (``[ WARN:0@…] global grfmt_png.cpp …``) while decoding.

    A file OpenCV cannot read gets one line of ours naming the file; its C++ warnings would
    only precede it. The previous level is restored, so a program using the library keeps its
    own OpenCV logging.
    """
    logging = getattr(getattr(cv2, "utils", None), "logging", None)
    if logging is None:
        yield
        return
    previous = logging.getLogLevel()
    logging.setLogLevel(logging.LOG_LEVEL_SILENT)
    try:
        yield
    finally:
        logging.setLogLevel(previous)


def _decode_image(data: bytes, path: Path, what: str) -> np.ndarray:
    """Decode PNG/PNM/BMP bytes with OpenCV into one channel, keeping 8 or 16 bit depth.

    Palette images are expanded through their palette. Images with several channels are
    accepted only when their colour channels are identical (a grey palette, or grey stored as
    RGB); a colour image is not a disparity map or a mask.
    """
    buffer = np.frombuffer(data, dtype=np.uint8)
    try:
        with quiet_opencv():
            image = cv2.imdecode(buffer, cv2.IMREAD_UNCHANGED)
    except cv2.error:
        image = None
    if image is None:
        raise InputError(
            f"{path}: cannot decode {what} image: expected a valid {path.suffix or 'image'} "
            f"file, found {len(data)} bytes that OpenCV cannot read (corrupt or wrong format)"
        )
    if image.ndim == 3:
        channels = image.shape[2]
        colour = image[:, :, : min(channels, 3)]
        if channels not in (3, 4) or not (
            np.array_equal(colour[:, :, 0], colour[:, :, 1])
            and np.array_equal(colour[:, :, 0], colour[:, :, 2])
        ):
            raise InputError(
                f"{path}: {what} image must have one channel (grey or grey palette), "
                f"found {channels} channels with different colours"
            )
        # Equal B, G, R: OpenCV's grey conversion (IMREAD_GRAYSCALE) gives exactly this value.
        image = colour[:, :, 0]
    if image.dtype not in (np.uint8, np.uint16):
        raise InputError(f"{path}: {what} image must be 8 or 16 bit unsigned, found {image.dtype}")
    if image.size == 0:
        raise InputError(f"{path}: {what} image is empty (0×0)")
    return np.ascontiguousarray(image)


def _checked_npy(stream: BinaryIO, available: int, path: Path) -> np.ndarray:
    """One ``.npy`` array, once its header's shape is known to fit the bytes that follow.

    ``np.load`` allocates what the header claims before reading: a damaged or hostile header
    (a shape of 10¹¹ elements in a 1 kB file) would ask for hundreds of GiB.
    """
    fmt = np.lib.format
    start = stream.tell()
    version = fmt.read_magic(stream)
    if version == (1, 0):
        shape, _, dtype = fmt.read_array_header_1_0(stream)
    elif version in ((2, 0), (3, 0)):
        shape, _, dtype = fmt.read_array_header_2_0(stream)
    else:
        raise ValueError(f"npy format version {version} is not supported")
    if dtype.hasobject:
        raise InputError(f"{path}: the array holds Python objects ({dtype}), expected numbers")
    needed = math.prod(shape) * dtype.itemsize
    body = available - (stream.tell() - start)
    if needed > body:
        raise InputError(
            f"{path}: the npy header claims a {'×'.join(map(str, shape))} {dtype} array "
            f"({needed} bytes) but only {body} bytes follow (damaged or not an npy array)"
        )
    stream.seek(start)
    return np.asarray(fmt.read_array(stream, allow_pickle=False))


def _load_npz(data: bytes, path: Path) -> np.ndarray:
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            keys = list(archive.files)
            if "arr_0" in keys:
                key = "arr_0"
            elif len(keys) == 1:
                key = keys[0]
            elif not keys:
                raise InputError(f"{path}: npz archive holds no array, expected one")
            else:
                raise InputError(
                    f"{path}: npz archive holds several arrays {keys}, expected 'arr_0' or "
                    f"a single array"
                )
            member = f"{key}.npy"
            with archive.zip.open(member) as stream:
                return _checked_npy(stream, archive.zip.getinfo(member).file_size, path)
    except InputError:
        raise
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise InputError(f"{path}: cannot decode npz archive ({_one_line(str(exc))})") from None


def _load_npy(data: bytes, path: Path) -> np.ndarray:
    try:
        return _checked_npy(io.BytesIO(data), len(data), path)
    except (ValueError, OSError, EOFError) as exc:
        raise InputError(f"{path}: cannot decode npy array ({_one_line(str(exc))})") from None


def _check_scale(scale: float | None, path: Path) -> float | None:
    if scale is None:
        return None
    try:
        value = float(scale)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"{path}: disparity scale must be a finite number > 0, got {scale!r}")
    return value


def _as_disparity(values: np.ndarray, path: Path, what: str = "disparity") -> np.ndarray:
    """Check an array from npy/npz/pfm is one real H×W map; return float32.

    ``what`` names the map in the errors (a confidence is read through this check too).
    """
    array = values
    if array.ndim == 3 and array.shape[2] == 1:
        array = array[:, :, 0]
    if array.ndim != 2:
        raise InputError(
            f"{path}: {what} must be one H×W channel, found shape {tuple(values.shape)}"
        )
    if array.size == 0:
        raise InputError(f"{path}: {what} map is empty, shape {tuple(values.shape)}")
    if array.dtype == np.bool_ or not np.issubdtype(array.dtype, np.number):
        raise InputError(f"{path}: {what} must be numeric, found dtype {array.dtype}")
    if np.iscomplexobj(array):
        raise InputError(f"{path}: {what} must be real, found dtype {array.dtype}")
    return np.ascontiguousarray(array, dtype=np.float32)


def _typed_file(path: PathLike, extensions: Sequence[str], what: str) -> tuple[Path, str]:
    """The file and its lower-case extension, or one line if ``what`` is not read from it."""
    file = Path(path)
    suffix = file.suffix.lower()
    if suffix not in extensions:
        raise InputError(
            f"{file}: unknown {what} file type {suffix or '(no extension)'!r}, expected "
            f"one of {', '.join(extensions)}"
        )
    return file, suffix


def read_disparity(path: PathLike, scale: float | None = None) -> np.ndarray:
    """Read a disparity map in pixels as a C-contiguous float32 H×W array.

    The format comes from the extension: ``.pfm``, ``.npy``, ``.npz`` (key ``arr_0``, else
    the only array), ``.png``/``.pgm``/``.ppm`` (one channel, palette expanded). The result is
    ``value / scale``. Default scale: 256 for 16-bit images (KITTI), 1 for everything else
    (8-bit images, float files). Invalid values stay as the source encodes them.
    """
    file, suffix = _typed_file(path, DISPARITY_EXTENSIONS, "disparity")
    factor = _check_scale(scale, file)
    if suffix == ".pfm":
        disparity = _as_disparity(read_pfm(file), file)
    else:
        data = _read_bytes(file, "disparity")
        if suffix == ".npy":
            disparity = _as_disparity(_load_npy(data, file), file)
        elif suffix == ".npz":
            disparity = _as_disparity(_load_npz(data, file), file)
        else:
            image = _decode_image(data, file, "disparity")
            if factor is None and image.dtype == np.uint16:
                factor = PNG16_SCALE
            disparity = image.astype(np.float32)
    if factor is not None and factor != 1.0:
        # Divide in float64 so that value/scale is rounded once, to the nearest float32.
        disparity = (disparity.astype(np.float64) / factor).astype(np.float32)
    return np.ascontiguousarray(disparity, dtype=np.float32)


CONFIDENCE_EXTENSIONS = (*DISPARITY_EXTENSIONS, ".tif", ".tiff")


def read_confidence(path: PathLike) -> np.ndarray:
    """Read a confidence map as an H×W array of the file's own values and type (no scaling).

    As :func:`read_disparity` reads files, but 8- and 16-bit images stay ``uint8`` / ``uint16``
    (their ties exact) and integer arrays keep their type; ``.tif``/``.tiff`` may be float.
    """
    file, suffix = _typed_file(path, CONFIDENCE_EXTENSIONS, "confidence")
    if suffix == ".pfm":
        return _as_disparity(read_pfm(file), file, "confidence")
    data = _read_bytes(file, "confidence")
    if suffix in (".tif", ".tiff"):
        with quiet_opencv():
            values = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
        if values is None:
            raise InputError(f"{file}: cannot decode the confidence TIFF (corrupt or wrong format)")
    elif suffix in (".npy", ".npz"):
        values = _load_npy(data, file) if suffix == ".npy" else _load_npz(data, file)
    else:
        return _decode_image(data, file, "confidence")
    checked = _as_disparity(values, file, "confidence")  # one real H×W map, or one line
    kind = np.asarray(values).dtype
    return np.ascontiguousarray(
        values.reshape(checked.shape), dtype=kind if kind.kind in "ui" else None
    )


def read_mask(path: PathLike) -> np.ndarray:
    """Read a mask as a uint8 H×W array with the file's values (e.g. 255 / 128 / 0).

    Palette images are expanded to grey. ``.npy``/``.npz`` boolean masks become 255/0. The
    values are kept so that the one rule, :func:`dispeval_ros.core.masks.inside_mask` (255
    inside, 128/0 outside, 0/1 or boolean; anything else refused), applies wherever they go.
    """
    file = Path(path)
    suffix = file.suffix.lower()
    if suffix not in MASK_EXTENSIONS:
        raise InputError(
            f"{file}: unknown mask file type {suffix or '(no extension)'!r}, expected one of "
            f"{', '.join(MASK_EXTENSIONS)}"
        )
    data = _read_bytes(file, "mask")
    if suffix in _IMAGE_EXTENSIONS:
        image = _decode_image(data, file, "mask")
        if image.dtype != np.uint8:
            raise InputError(f"{file}: mask image must be 8 bit, found {image.dtype}")
        return image
    values = _load_npy(data, file) if suffix == ".npy" else _load_npz(data, file)
    if values.ndim != 2 or values.size == 0:
        raise InputError(f"{file}: mask must be a non-empty H×W array, found {values.shape}")
    if values.dtype == np.bool_:
        return np.where(values, np.uint8(255), np.uint8(0))
    if values.dtype == np.uint8:
        return np.ascontiguousarray(values)
    raise InputError(f"{file}: mask array must be bool or uint8, found {values.dtype}")


def write_disparity_png16(path: PathLike, disparity: np.ndarray) -> None:
    """Write a disparity map in KITTI's encoding: uint16 PNG of ``round(d·256)``.

    Invalid points (not finite or ≤ 0) become 0. A valid disparity too small to survive the
    rounding is written as 1 (1/256 px) so that it stays valid. Values above 65535/256 px
    cannot be encoded and raise :class:`InputError`.
    """
    file = Path(path)
    values = np.asarray(disparity)
    if values.ndim != 2 or values.size == 0:
        raise InputError(
            f"{file}: KITTI PNG needs a non-empty H×W disparity, got shape {values.shape}"
        )
    values = values.astype(np.float64)
    valid = np.isfinite(values) & (values > 0)
    scaled = np.zeros(values.shape, dtype=np.float64)
    scaled[valid] = np.maximum(np.round(values[valid] * PNG16_SCALE), 1.0)
    if valid.any() and scaled.max() > _PNG16_MAX:
        raise InputError(
            f"{file}: KITTI PNG encodes disparities up to {_PNG16_MAX / PNG16_SCALE:.4f} px, "
            f"got {values[valid].max():.4f}"
        )
    if file.suffix.lower() != ".png":
        raise InputError(f"{file}: KITTI disparity must be written as .png, got {file.suffix!r}")
    try:
        ok = cv2.imwrite(str(file), scaled.astype(np.uint16))
    except cv2.error as exc:
        raise InputError(f"{file}: cannot write PNG ({_one_line(str(exc))})") from None
    if not ok:
        raise InputError(f"{file}: cannot write PNG (OpenCV refused the path)")


def read_stereo_pair(left: PathLike, right: PathLike) -> tuple[np.ndarray, np.ndarray]:
    """The left and right rectified images as 8-bit grey (colour through BT.601 weights).

    Both must be 8 bit and both grey or both colour: a colour image beside a grey one, or a
    16-bit image, is one line naming the file.
    """
    images = []
    for side, name in (("left", left), ("right", right)):
        file = Path(name)
        if file.suffix.lower() not in _IMAGE_EXTENSIONS:
            raise InputError(
                f"{file}: unknown image file type {file.suffix or '(no extension)'!r} for the "
                f"{side} image, expected one of {', '.join(_IMAGE_EXTENSIONS)}"
            )
        buffer = np.frombuffer(_read_bytes(file, f"{side} image"), dtype=np.uint8)
        with quiet_opencv():
            image = cv2.imdecode(buffer, cv2.IMREAD_UNCHANGED)
        if image is None:
            raise InputError(f"{file}: cannot decode the {side} image (corrupt or wrong format)")
        if image.dtype != np.uint8:
            raise InputError(f"{file}: the {side} image must be 8 bit, found {image.dtype}")
        images.append((file, image))
    (left_file, left_image), (right_file, right_image) = images
    colours = [image.ndim == 3 for _, image in images]
    if colours[0] != colours[1]:
        shown = ["colour" if colour else "grey" for colour in colours]
        raise InputError(
            f"{left_file} is {shown[0]} but {right_file} is {shown[1]}: give both images in "
            "one kind (both grey or both colour)"
        )
    return _grey(left_image), _grey(right_image)


def _grey(image: np.ndarray) -> np.ndarray:
    if image.ndim == 2:
        return np.ascontiguousarray(image)
    code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
    return cv2.cvtColor(image, code)
