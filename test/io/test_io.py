"""Tests of the file readers: PFM, disparity images, masks, calibrations and scene folders."""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from PIL import Image

from dispeval_ros.core.camera import Camera
from dispeval_ros.errors import (
    CalibrationError,
    InputError,
    LayoutError,
    ShapeMismatchError,
)
from dispeval_ros.io import (
    Scene,
    list_frames,
    load_scene,
    read_calib,
    read_disparity,
    read_mask,
    read_pfm,
    write_disparity_png16,
    write_pfm,
)

# ------------------------------------------------------------------------------- helpers


def pfm_bytes(
    array: np.ndarray, *, little: bool = True, header: str | None = None, scale: str = "1"
) -> bytes:
    """A PFM file built by hand: rows bottom-to-top, given byte order and header text."""
    height, width = array.shape[:2]
    magic = "Pf" if array.ndim == 2 else "PF"
    sign = "-" if little else ""
    text = header or f"{magic}\n{width} {height}\n{sign}{scale}\n"
    body = np.ascontiguousarray(array[::-1], dtype="<f4" if little else ">f4").tobytes()
    return text.encode("ascii") + body


def simple_pfm_reader(path: Path) -> np.ndarray:
    """Independent straightforward reader: three header lines, then the data."""
    with path.open("rb") as stream:
        magic = stream.readline().strip()
        width, height = (int(v) for v in stream.readline().split())
        scale = float(stream.readline().strip())
        channels = 3 if magic == b"PF" else 1
        data = np.fromfile(stream, dtype="<f4" if scale < 0 else ">f4")
    shape = (height, width, 3) if channels == 3 else (height, width)
    return np.flipud(data.reshape(shape)).astype(np.float32)


def assert_one_line_naming(error: pytest.ExceptionInfo[BaseException], path: Path) -> None:
    message = str(error.value)
    assert "\n" not in message
    assert path.name in message, message


SAMPLE = np.array([[1.5, 2.0, np.inf], [0.0, 4.25, 5.0]], dtype=np.float32)


# ----------------------------------------------------------------------------------- PFM


@pytest.mark.parametrize("little", [True, False])
def test_pfm_both_endiannesses(tmp_path: Path, little: bool) -> None:
    path = tmp_path / "d.pfm"
    path.write_bytes(pfm_bytes(SAMPLE, little=little))
    result = read_pfm(path)
    assert result.dtype == np.float32
    assert result.dtype.byteorder in ("=", "|") or result.dtype.isnative
    assert result.flags.c_contiguous
    assert result.flags.writeable
    np.testing.assert_array_equal(result, SAMPLE)
    assert result[0, 0] == 1.5  # rows came bottom-to-top: the first stored row is the last


@pytest.mark.parametrize(
    "header",
    [
        "Pf\n3 2\n-1\n",
        "Pf \n3 2 \n-1.0\n",  # trailing spaces (sceneflow-flyingthings3d-seq)
        "Pf\n3 2\n-0.003922\n",  # MiddEval3's scale: the magnitude is not a factor
        "Pf\r\n3 2\r\n-1\r\n",
        "Pf\n# written by a tool\n3   2\n-1\n",
        "Pf\t3\t2\t-1\n",
        "Pf 3 2 -1 \n",
        "Pf\n3\n2\n-1\n# trailing comment\n",
        "Pf\n\n  3 2\n\n-1\n",
    ],
)
def test_pfm_header_variants(tmp_path: Path, header: str) -> None:
    path = tmp_path / "v.pfm"
    path.write_bytes(pfm_bytes(SAMPLE, header=header))
    np.testing.assert_array_equal(read_pfm(path), SAMPLE)


def test_pfm_colour(tmp_path: Path) -> None:
    colour = np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3)
    path = tmp_path / "c.pfm"
    path.write_bytes(pfm_bytes(colour))
    np.testing.assert_array_equal(read_pfm(path), colour)
    with pytest.raises(InputError) as error:
        read_disparity(path)
    assert_one_line_naming(error, path)


def test_pfm_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "r.pfm"
    write_pfm(path, SAMPLE)
    assert path.read_bytes().startswith(b"Pf\n3 2\n-1\n")
    np.testing.assert_array_equal(read_pfm(path), SAMPLE)
    np.testing.assert_array_equal(simple_pfm_reader(path), SAMPLE)
    np.testing.assert_array_equal(read_disparity(path), SAMPLE)


@settings(max_examples=40, deadline=None)
@given(
    hnp.arrays(
        np.float32,
        hnp.array_shapes(min_dims=2, max_dims=2, min_side=1, max_side=12),
        elements=st.floats(allow_nan=True, width=32),
    )
)
def test_pfm_round_trip_property(tmp_path_factory: pytest.TempPathFactory, array: np.ndarray):
    path = tmp_path_factory.mktemp("pfm") / "p.pfm"
    write_pfm(path, array)
    np.testing.assert_array_equal(read_pfm(path), array)


def test_pfm_truncated(tmp_path: Path) -> None:
    path = tmp_path / "t.pfm"
    path.write_bytes(pfm_bytes(SAMPLE)[:-5])
    with pytest.raises(InputError) as error:
        read_pfm(path)
    assert_one_line_naming(error, path)
    assert "expected 24 bytes" in str(error.value)
    assert "found 19" in str(error.value)


@pytest.mark.parametrize(
    "content",
    [
        b"",
        b"P5\n3 2\n255\n",
        b"Pf\n3 x\n-1\n" + bytes(24),
        b"Pf\n3 2\n0\n" + bytes(24),
        b"Pf\n3 2\nabc\n" + bytes(24),
        b"Pf\n-3 2\n-1\n" + bytes(24),
        b"Pf\n3 2\n",
        b"Pf\n3 2\n-1",
        b"Pfx\n3 2\n-1\n" + bytes(24),
    ],
)
def test_pfm_bad_files(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "bad.pfm"
    path.write_bytes(content)
    with pytest.raises(InputError) as error:
        read_pfm(path)
    assert_one_line_naming(error, path)


def test_pfm_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nothere.pfm"
    with pytest.raises(InputError) as error:
        read_pfm(path)
    assert_one_line_naming(error, path)


def test_write_pfm_rejects_bad_shape(tmp_path: Path) -> None:
    path = tmp_path / "w.pfm"
    with pytest.raises(InputError) as error:
        write_pfm(path, np.zeros((2, 3, 2), np.float32))
    assert_one_line_naming(error, path)


# ------------------------------------------------------------------------- read_disparity


def test_npy_and_npz(tmp_path: Path) -> None:
    np.save(tmp_path / "d.npy", SAMPLE.astype(np.float64))
    result = read_disparity(tmp_path / "d.npy")
    assert result.dtype == np.float32
    np.testing.assert_array_equal(result, SAMPLE)
    np.savez(tmp_path / "a.npz", SAMPLE)
    np.testing.assert_array_equal(read_disparity(tmp_path / "a.npz"), SAMPLE)
    np.savez(tmp_path / "b.npz", disparity=SAMPLE)
    np.testing.assert_array_equal(read_disparity(tmp_path / "b.npz"), SAMPLE)
    np.savez(tmp_path / "c.npz", SAMPLE, other=SAMPLE)  # arr_0 wins
    np.testing.assert_array_equal(read_disparity(tmp_path / "c.npz"), SAMPLE)
    np.testing.assert_array_equal(read_disparity(tmp_path / "d.npy", scale=2), SAMPLE / 2)


def test_npz_several_arrays(tmp_path: Path) -> None:
    path = tmp_path / "several.npz"
    np.savez(path, left=SAMPLE, right=SAMPLE)
    with pytest.raises(InputError) as error:
        read_disparity(path)
    assert_one_line_naming(error, path)
    assert "left" in str(error.value)
    assert "right" in str(error.value)


def test_png16_default_scale_256(tmp_path: Path) -> None:
    raw = np.array([[0, 256, 512], [65535, 1, 3000]], dtype=np.uint16)
    path = tmp_path / "kitti.png"
    cv2.imwrite(str(path), raw)
    result = read_disparity(path)
    assert result.dtype == np.float32
    np.testing.assert_array_equal(result, raw / 256.0)
    assert result[0, 0] == 0  # invalid stays 0
    np.testing.assert_array_equal(read_disparity(path, scale=100), np.float32(raw / 100.0))


def test_png8_default_scale_1(tmp_path: Path) -> None:
    raw = np.array([[0, 16, 240]], dtype=np.uint8)
    path = tmp_path / "gt.png"
    cv2.imwrite(str(path), raw)
    np.testing.assert_array_equal(read_disparity(path), raw.astype(np.float32))
    np.testing.assert_array_equal(read_disparity(path, scale=16), raw / 16.0)
    pgm = tmp_path / "gt.pgm"
    cv2.imwrite(str(pgm), raw)
    np.testing.assert_array_equal(read_disparity(pgm, scale=4), raw / 4.0)


def make_palette_png(path: Path, values: np.ndarray) -> None:
    """A palette PNG whose indices (0, 1, 2, ...) are NOT the grey values they stand for."""
    levels = np.unique(values)
    index = np.searchsorted(levels, values).astype(np.uint8)
    image = Image.fromarray(index, mode="P")
    palette = []
    for level in levels:
        palette += [int(level)] * 3
    image.putpalette(palette)
    image.save(path)
    assert Image.open(path).mode == "P"


def test_palette_png(tmp_path: Path) -> None:
    values = np.array([[0, 128, 255], [255, 0, 128]], dtype=np.uint8)
    path = tmp_path / "mask.png"
    make_palette_png(path, values)
    pillow = np.asarray(Image.open(path).convert("L"))
    opencv = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE | cv2.IMREAD_ANYDEPTH)
    np.testing.assert_array_equal(pillow, values)
    mask = read_mask(path)
    assert mask.dtype == np.uint8
    np.testing.assert_array_equal(mask, pillow)
    np.testing.assert_array_equal(mask, opencv)
    np.testing.assert_array_equal(read_disparity(path, scale=4), pillow / 4.0)


def test_colour_image_rejected(tmp_path: Path) -> None:
    colour = np.zeros((4, 5, 3), np.uint8)
    colour[..., 2] = 200
    path = tmp_path / "colour.png"
    cv2.imwrite(str(path), colour)
    for reader in (read_disparity, read_mask):
        with pytest.raises(InputError) as error:
            reader(path)
        assert_one_line_naming(error, path)
    grey_rgb = np.repeat(np.array([[[7]], [[9]]], np.uint8), 3, axis=2)
    grey_path = tmp_path / "grey.ppm"
    cv2.imwrite(str(grey_path), grey_rgb)
    np.testing.assert_array_equal(read_disparity(grey_path), [[7.0], [9.0]])


def test_mask_values_kept(tmp_path: Path) -> None:
    values = np.array([[0, 128, 255]], np.uint8)
    path = tmp_path / "m.png"
    cv2.imwrite(str(path), values)
    np.testing.assert_array_equal(read_mask(path), values)
    np.save(tmp_path / "m.npy", np.array([[True, False]]))
    np.testing.assert_array_equal(read_mask(tmp_path / "m.npy"), [[255, 0]])
    deep = tmp_path / "deep.png"
    cv2.imwrite(str(deep), values.astype(np.uint16) * 256)
    with pytest.raises(InputError) as error:
        read_mask(deep)
    assert_one_line_naming(error, deep)


@pytest.mark.parametrize(
    ("name", "content"),
    [
        ("d.tiff", b"II*\x00"),
        ("d", b"whatever"),
        ("d.png", b""),
        ("d.png", b"\x89PNG\r\n\x1a\nnot really a png"),
        ("d.pgm", b"P5\n10 10\n255\n\x00"),
        ("d.npy", b"\x93NUMPY garbage"),
        ("d.npz", b"PK\x03\x04 broken zip"),
        ("d.npy", b""),
    ],
)
def test_disparity_bad_files(tmp_path: Path, name: str, content: bytes) -> None:
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(InputError) as error:
        read_disparity(path)
    assert_one_line_naming(error, path)


def test_disparity_bad_arrays(tmp_path: Path) -> None:
    cases = {
        "3d.npy": np.zeros((2, 2, 2), np.float32),
        "1d.npy": np.zeros(4, np.float32),
        "empty.npy": np.zeros((0, 3), np.float32),
        "bool.npy": np.zeros((2, 2), bool),
        "text.npy": np.array([["a", "b"]]),
    }
    for name, array in cases.items():
        path = tmp_path / name
        np.save(path, array)
        with pytest.raises(InputError) as error:
            read_disparity(path)
        assert_one_line_naming(error, path)
    empty = tmp_path / "empty.npz"
    np.savez(empty)
    with pytest.raises(InputError) as error:
        read_disparity(empty)
    assert_one_line_naming(error, empty)


def test_disparity_missing_and_directory(tmp_path: Path) -> None:
    for path in (tmp_path / "missing.png", tmp_path / "folder.png"):
        if path.name == "folder.png":
            path.mkdir()
        with pytest.raises(InputError) as error:
            read_disparity(path)
        assert_one_line_naming(error, path)


@pytest.mark.parametrize("scale", [0, -1, float("nan"), float("inf")])
def test_disparity_bad_scale(tmp_path: Path, scale: float) -> None:
    path = tmp_path / "s.npy"
    np.save(path, SAMPLE)
    with pytest.raises(InputError) as error:
        read_disparity(path, scale=scale)
    assert_one_line_naming(error, path)


def test_write_disparity_png16(tmp_path: Path) -> None:
    disparity = np.array([[0.0, -1.0, np.inf, np.nan], [1.0 / 1024, 10.3, 255.99, 100.0]])
    path = tmp_path / "out.png"
    write_disparity_png16(path, disparity)
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert raw is not None
    assert raw.dtype == np.uint16
    np.testing.assert_array_equal(raw[0], [0, 0, 0, 0])
    np.testing.assert_array_equal(raw[1], [1, round(10.3 * 256), round(255.99 * 256), 25600])
    back = read_disparity(path)
    assert np.all(np.abs(back[1, 1:] - disparity[1, 1:]) <= 1 / 512)
    with pytest.raises(InputError) as error:
        write_disparity_png16(tmp_path / "big.png", np.array([[300.0]]))
    assert_one_line_naming(error, tmp_path / "big.png")
    with pytest.raises(InputError):
        write_disparity_png16(tmp_path / "bad.png", np.zeros((2, 2, 3)))


# ----------------------------------------------------------------------------------- calib

MIDDLEBURY_CALIB = (
    "cam0=[ 1038.018 0 322.037 ; 0 1038.018 243.393 ; 0 0 1 ] \n"
    " cam1=[1038.018 0 375.308; 0 1038.018 243.393; 0 0 1]\n"
    " doffs= 53.271 \n"
    "baseline= 176.252\n"
    " width= 718\n"
    "height= 496 \n"
    " ndisp= 73\n"
    " vmin= 8 \n"
)


def test_middlebury_calib(tmp_path: Path) -> None:
    path = tmp_path / "calib.txt"
    path.write_text(MIDDLEBURY_CALIB)
    camera = read_calib(path)
    assert camera.f == 1038.018
    assert camera.baseline == pytest.approx(0.176252)  # mm → m
    assert camera.doffs == 53.271
    assert camera.unit == "m"
    derived = tmp_path / "derived.txt"
    derived.write_text(MIDDLEBURY_CALIB.replace(" doffs= 53.271 \n", ""))
    assert read_calib(derived).doffs == pytest.approx(375.308 - 322.037)


@pytest.mark.parametrize(
    ("text", "field"),
    [
        (MIDDLEBURY_CALIB.replace("baseline= 176.252\n", ""), "baseline"),
        (MIDDLEBURY_CALIB.replace(" doffs= 53.271 \n", "").replace(" cam1=", " camX="), "doffs"),
        (MIDDLEBURY_CALIB.replace("53.271", "abc"), "doffs"),
        (MIDDLEBURY_CALIB.replace("176.252", "-176.252"), "baseline"),
        (MIDDLEBURY_CALIB.replace("176.252", "0"), "baseline"),
        (MIDDLEBURY_CALIB.replace("[ 1038.018 0 322.037", "[ 0 0 322.037"), "cam0"),
        (MIDDLEBURY_CALIB.replace("[ 1038.018 0 322.037 ;", "[ 1038.018 322.037 ;"), "cam0"),
        (MIDDLEBURY_CALIB.replace("[1038.018 0 375.308;", "[1038.018 0 x;"), "cam1"),
        (MIDDLEBURY_CALIB.replace(" width= 718", " width= wide"), "width"),
    ],
)
def test_middlebury_calib_errors(tmp_path: Path, text: str, field: str) -> None:
    path = tmp_path / "calib.txt"
    path.write_text(text)
    with pytest.raises(CalibrationError) as error:
        read_calib(path)
    assert_one_line_naming(error, path)
    assert field in str(error.value)


P2 = "7.215377e+02 0.000000e+00 6.095593e+02 4.485728e+01"
P2_ROWS = (P2, "0 7.215377e+02 1.728540e+02 2.163791e-01", "0 0 1 2.745884e-03")
P3 = "7.215377e+02 0.000000e+00 6.095593e+02 -3.395242e+02"
P3_ROWS = (P3, "0 7.215377e+02 1.728540e+02 2.199936e+00", "0 0 1 2.729905e-03")
KITTI_BASELINE = (44.85728 + 339.5242) / 721.5377


@pytest.mark.parametrize(
    "text",
    [
        "KITTI\n\nP_rect_02: \n" + " \n".join(P2_ROWS) + "\n\nP_rect_03: \n" + "\n".join(P3_ROWS),
        "calib_time: 09-Jan-2012 13:57:47\nS_rect_02: 1.242000e+03 3.750000e+02\n"
        "P_rect_02: " + " ".join(P2_ROWS) + "\nP_rect_03: " + " ".join(P3_ROWS) + "\n",
        "P0: " + " ".join(P2_ROWS) + "\nP2: " + " ".join(P2_ROWS) + "\nP3: " + " ".join(P3_ROWS),
    ],
)
def test_kitti_calib(tmp_path: Path, text: str) -> None:
    path = tmp_path / "calib.txt"
    path.write_text(text)
    camera = read_calib(path)
    assert camera.f == pytest.approx(721.5377)
    assert camera.baseline == pytest.approx(KITTI_BASELINE)
    assert camera.doffs == 0


def test_kitti_calib_doffs_sign(tmp_path: Path) -> None:
    path = tmp_path / "calib.txt"
    right = P3.replace("6.095593e+02", "6.195593e+02", 1)
    path.write_text(f"P_rect_02: {' '.join(P2_ROWS)}\nP_rect_03: {right} 0 1 2 3 4 5 6 7\n")
    assert read_calib(path).doffs == pytest.approx(10.0)  # cx_right − cx_left


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("P_rect_02: " + " ".join(P2_ROWS) + "\n", "P_rect_03"),
        ("P_rect_03: " + " ".join(P3_ROWS) + "\n", "P_rect_02"),
        ("P_rect_02: " + " ".join(P3_ROWS) + "\nP_rect_03: " + " ".join(P2_ROWS), "baseline"),
        ("P_rect_02: " + P2 + "\nP_rect_03: " + " ".join(P3_ROWS), "P_rect_02"),
        ("P2: " + " ".join(P2_ROWS).replace("7.215", "x.215", 1) + "\nP3: " + P3, "P2"),
    ],
)
def test_kitti_calib_errors(tmp_path: Path, text: str, field: str) -> None:
    path = tmp_path / "calib_cam_to_cam.txt"
    path.write_text(text)
    with pytest.raises(CalibrationError) as error:
        read_calib(path)
    assert_one_line_naming(error, path)
    assert field in str(error.value)


def test_q_matrix_matches_opencv(tmp_path: Path) -> None:
    """A Q from cv2.stereoRectify (principal points differ) gives OpenCV's depths."""
    f, baseline, cx_left, cx_right = 700.0, 0.12, 300.0, 340.0
    k1 = np.array([[f, 0, cx_left], [0, f, 240], [0, 0, 1]])
    k2 = np.array([[f, 0, cx_right], [0, f, 240], [0, 0, 1]])
    translation = np.array([[-baseline], [0.0], [0.0]])
    _, _, p1, p2, q, _, _ = cv2.stereoRectify(
        k1, np.zeros(5), k2, np.zeros(5), (640, 480), np.eye(3), translation, flags=0
    )
    path = tmp_path / "Q.dat"
    path.write_text("\n".join(" ".join(f"{v:.12e}" for v in row) for row in q))
    camera = read_calib(path)
    assert camera.f == pytest.approx(q[2, 3])
    assert camera.baseline == pytest.approx(baseline)
    assert camera.doffs == pytest.approx(p2[0, 2] - p1[0, 2]) == pytest.approx(40.0)
    flipped = tmp_path / "Q_flipped.dat"  # Q[2,3] and Q[3,:] negated: the same camera
    q_flipped = q.copy()
    q_flipped[2, 3] *= -1
    q_flipped[3] *= -1
    flipped.write_text("\n".join(" ".join(f"{v:.12e}" for v in row) for row in q_flipped))
    assert read_calib(flipped).doffs == pytest.approx(camera.doffs)
    assert read_calib(flipped).baseline == pytest.approx(camera.baseline)
    for disparity in (5.0, 20.0, 64.0):
        point = q @ np.array([100.0, 50.0, disparity, 1.0])
        assert camera.depth(disparity) == pytest.approx(point[2] / point[3])


@pytest.mark.parametrize(
    ("text", "word"),
    [
        ("1 0 0 -320\n0 1 0 -240\n0 0 0 320\n0 0 4\n", "16 numbers"),
        ("1 0 0 -320\n0 1 0 -240\n0 0 0 320\n0 0 0 0\n", "Q[3,2]"),
        ("1 0 0 -320\n0 1 0 -240\n0 0 0 0\n0 0 4 0\n", "Q[2,3]"),
        ("hello world\n", "unknown calibration format"),
        ("", "empty"),
    ],
)
def test_q_and_format_errors(tmp_path: Path, text: str, word: str) -> None:
    path = tmp_path / "Q.dat"
    path.write_text(text)
    with pytest.raises(CalibrationError) as error:
        read_calib(path)
    assert_one_line_naming(error, path)
    assert word in str(error.value)


def test_calib_missing_or_binary(tmp_path: Path) -> None:
    missing = tmp_path / "calib.txt"
    with pytest.raises(CalibrationError) as error:
        read_calib(missing)
    assert_one_line_naming(error, missing)
    binary = tmp_path / "calib.bin"
    binary.write_bytes(b"\xff\xfe\x00\x81")
    with pytest.raises(CalibrationError) as error:
        read_calib(binary)
    assert_one_line_naming(error, binary)


# ---------------------------------------------------------------------- scenes (synthetic)


def test_unknown_layout(tmp_path: Path) -> None:
    for index in range(12):
        (tmp_path / f"file{index:02d}.txt").write_text("x")
    with pytest.raises(LayoutError) as error:
        load_scene(tmp_path)
    message = str(error.value)
    assert "\n" not in message
    assert "disp0GT.pfm" in message
    assert "file00.txt" in message
    assert "12 entries" in message


def test_scene_path_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError):
        load_scene(tmp_path / "absent")
    file = tmp_path / "a.txt"
    file.write_text("x")
    with pytest.raises(LayoutError):
        load_scene(file)


def test_middeval3_without_calib(tmp_path: Path) -> None:
    write_pfm(tmp_path / "disp0GT.pfm", SAMPLE)
    with pytest.raises(CalibrationError) as error:
        load_scene(tmp_path)
    assert "calib.txt" in str(error.value)


def test_middeval3_synthetic(tmp_path: Path) -> None:
    write_pfm(tmp_path / "disp0GT.pfm", SAMPLE)
    write_pfm(tmp_path / "disp1GT.pfm", SAMPLE * 2)
    (tmp_path / "calib.txt").write_text(MIDDLEBURY_CALIB)
    cv2.imwrite(str(tmp_path / "mask0nocc.png"), np.array([[255, 128, 0]] * 2, np.uint8))
    scene = load_scene(tmp_path)
    assert isinstance(scene, Scene)
    assert scene.layout == "middeval3"
    assert scene.gt_right is not None
    np.testing.assert_array_equal(scene.gt_right, SAMPLE * 2)
    np.testing.assert_array_equal(scene.masks["nonocc"], [[True, False, False]] * 2)
    cv2.imwrite(str(tmp_path / "mask0nocc.png"), np.zeros((3, 3), np.uint8))
    with pytest.raises(ShapeMismatchError) as error:
        load_scene(tmp_path)
    assert "mask0nocc.png" in str(error.value)


def test_sceneflow_and_tartanair_need_q(tmp_path: Path) -> None:
    sceneflow = tmp_path / "sf"
    (sceneflow / "Disparity").mkdir(parents=True)
    write_pfm(sceneflow / "Disparity" / "0001.pfm", SAMPLE)
    with pytest.raises(CalibrationError) as error:
        load_scene(sceneflow)
    assert "Q.dat" in str(error.value)
    tartan = tmp_path / "ta"
    tartan.mkdir()
    np.save(tartan / "000001_left_disp.npy", SAMPLE)
    with pytest.raises(CalibrationError) as error:
        load_scene(tartan)
    assert "Q.dat" in str(error.value)


def test_sceneflow_synthetic_frames(tmp_path: Path) -> None:
    disparity = tmp_path / "Disparity"
    disparity.mkdir()
    for frame in ("0002", "0001"):
        write_pfm(disparity / f"{frame}.pfm", SAMPLE + int(frame))
    (disparity / "Q.dat").write_text("1 0 0 -1\n0 1 0 -1\n0 0 0 100\n0 0 2 0\n")
    frames = list_frames(tmp_path)
    assert [scene.name.rsplit("_", 1)[1] for scene in frames] == ["0001", "0002"]
    assert all(scene.camera == Camera(100.0, 0.5, 0.0, "scene") for scene in frames)
    np.testing.assert_array_equal(load_scene(tmp_path).gt, SAMPLE + 1)


def test_kitti_flat_folder_occ_noc(tmp_path: Path) -> None:
    occ = np.array([[0, 2560, 512]], np.uint16)
    noc = np.array([[0, 2560, 0]], np.uint16)
    cv2.imwrite(str(tmp_path / "disp_occ_0.png"), occ)
    cv2.imwrite(str(tmp_path / "disp_noc_0.png"), noc)
    cv2.imwrite(str(tmp_path / "image_2.png"), np.zeros((1, 3, 3), np.uint8))
    scene = load_scene(tmp_path)
    assert scene.layout == "kitti"
    assert scene.camera is None
    assert scene.left == tmp_path / "image_2.png"
    np.testing.assert_array_equal(scene.gt, [[0, 10, 2]])
    np.testing.assert_array_equal(scene.masks["nonocc"], [[False, True, False]])


def test_kitti_calibration_choice(tmp_path: Path) -> None:
    cv2.imwrite(str(tmp_path / "disp_gt.png"), np.array([[0, 2560]], np.uint16))
    (tmp_path / "calib_imu_to_velo.txt").write_text("R: 1 0 0 0 1 0 0 0 1\nT: 0 0 0\n")
    (tmp_path / "Q.dat").write_text("1 0 0 -1\n0 1 0 -1\n0 0 0 100\n0 0 2 0\n")
    assert load_scene(tmp_path).camera == Camera(100.0, 0.5)  # no P_rect: Q.dat
    rows = " ".join(P2_ROWS) + "\nP_rect_03: " + " ".join(P3_ROWS)
    (tmp_path / "calib_cam_to_cam.txt").write_text("P_rect_02: " + rows)
    camera = load_scene(tmp_path).camera
    assert camera is not None
    assert camera.f == pytest.approx(721.5377)
    (tmp_path / "calib_cam_to_cam.txt").write_text("P_rect_02: " + " ".join(P2_ROWS))
    with pytest.raises(CalibrationError) as error:  # a broken P_rect file is not skipped
        load_scene(tmp_path)
    assert "P_rect_03" in str(error.value)


def test_middlebury2001_synthetic(tmp_path: Path) -> None:
    cv2.imwrite(str(tmp_path / "groundtruth.png"), np.array([[0, 32, 64]], np.uint8))
    (tmp_path / "info.txt").write_text("8\n10")
    make_palette_png(tmp_path / "disc.png", np.array([[0, 128, 255]], np.uint8))
    scene = load_scene(tmp_path)
    assert scene.layout == "middlebury2001"
    np.testing.assert_array_equal(scene.gt, [[0, 4, 8]])
    np.testing.assert_array_equal(scene.masks["disc"], [[False, False, True]])
    (tmp_path / "info.txt").write_text("scale\n")
    with pytest.raises(InputError) as error:
        load_scene(tmp_path)
    assert "info.txt" in str(error.value)
    (tmp_path / "info.txt").unlink()
    with pytest.raises(LayoutError) as layout_error:
        load_scene(tmp_path)
    assert "info.txt" in str(layout_error.value)


# -------------------------------------------------------------------------- real data

MIDDEVAL3_SCENES = [
    "Adirondack", "ArtL", "Jadeplant", "Motorcycle", "MotorcycleE", "Piano", "PianoL", "Pipes",
    "Playroom", "Playtable", "PlaytableP", "Recycle", "Shelves", "Teddy", "Vintage",
]  # fmt: skip


def calib_matrix(text: str, name: str) -> list[float]:
    match = re.search(rf"{name}\s*=\s*\[([^\]]*)\]", text)
    assert match, name
    return [float(v) for v in match.group(1).replace(";", " ").split()]


@pytest.mark.data
@pytest.mark.parametrize("scene", MIDDEVAL3_SCENES)
def test_real_middeval3_calib(shared_data: Path, scene: str) -> None:
    path = shared_data / "middeval3-training-Q" / scene / "calib.txt"
    text = path.read_text()
    cam0, cam1 = calib_matrix(text, "cam0"), calib_matrix(text, "cam1")
    baseline_mm = float(re.search(r"baseline\s*=\s*([\d.]+)", text).group(1))  # type: ignore[union-attr]
    camera = read_calib(path)
    assert camera.f == cam0[0] == cam1[0]
    assert camera.f == cam0[4]
    assert camera.baseline == pytest.approx(baseline_mm / 1000)
    assert 0.05 < camera.baseline < 0.5  # metres
    # the file's doffs is rounded separately: Pipes, Shelves, Vintage differ by 0.001
    assert camera.doffs == pytest.approx(cam1[2] - cam0[2], abs=1.5e-3)
    assert camera.unit == "m"


def real_pfms(root: Path) -> list[Path]:
    return sorted(set(root.glob("*/*/*.pfm")))


@pytest.mark.data
def test_real_pfm_matches_simple_reader(shared_data: Path) -> None:
    files = real_pfms(shared_data)
    assert len(files) == 15 + 2 + 3
    for path in files:
        ours = read_pfm(path)
        reference = simple_pfm_reader(path)
        assert ours.shape == reference.shape
        np.testing.assert_array_equal(ours, reference, err_msg=str(path))
        assert ours.flags.c_contiguous
        assert ours.dtype.isnative


@pytest.mark.data
def test_real_middeval3_pfm_scale_not_applied(shared_data: Path) -> None:
    """OpenCV multiplies MiddEval3's values by |scale| = 1/255; the true disparities are not."""
    path = shared_data / "middeval3-training-Q" / "Teddy" / "disp0GT.pfm"
    ours = read_pfm(path)
    valid = np.isfinite(ours)
    assert 10 < ours[valid].max() < 64  # Teddy quarter size: ndisp = 64
    opencv = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if opencv is not None:  # OpenCV 5 reads this one but scales it
        np.testing.assert_allclose(opencv[valid] / 255.0, ours[valid], rtol=1e-3)


@pytest.mark.data
@pytest.mark.parametrize("scene", MIDDEVAL3_SCENES)
def test_real_middeval3_mask_agrees_with_gt(shared_data: Path, scene: str) -> None:
    folder = shared_data / "middeval3-training-Q" / scene
    gt = read_disparity(folder / "disp0GT.pfm")
    mask = read_mask(folder / "mask0nocc.png")
    assert mask.shape == gt.shape
    assert set(np.unique(mask).tolist()) <= {0, 128, 255}
    unknown = ~np.isfinite(gt)
    assert unknown.any()
    assert np.all(mask[unknown] == 0)
    assert np.all(np.isfinite(gt[mask > 0]))
    assert np.all(gt[mask > 0] > 0)
    loaded = load_scene(folder)
    np.testing.assert_array_equal(loaded.masks["nonocc"], mask == 255)


MIDDLEBURY_COUNTS = {
    "tsukuba": (87696, 85438, 15790),
    "venus": (150282, 147513, 10540),
    "teddy": (165344, 147651, 40517),
    "cones": (163321, 143926, 47189),
}


@pytest.mark.data
@pytest.mark.parametrize("scene", sorted(MIDDLEBURY_COUNTS))
def test_real_middlebury_masks(shared_data: Path, scene: str) -> None:
    folder = shared_data / "middlebury-2001-2003" / scene
    loaded = load_scene(folder)
    assert loaded.layout == "middlebury2001"
    assert loaded.camera is None
    counts = tuple(int(loaded.masks[name].sum()) for name in ("all", "nonocc", "disc"))
    assert counts == MIDDLEBURY_COUNTS[scene]
    for name in ("all", "nonocc", "disc"):
        pillow = np.asarray(Image.open(folder / f"{name}.png").convert("L"))
        np.testing.assert_array_equal(read_mask(folder / f"{name}.png"), pillow)
    valid = np.isfinite(loaded.gt) & (loaded.gt > 0)
    # "all" is the evaluated region: points with GT, minus a border in venus
    assert not np.any(loaded.masks["all"] & ~valid)
    assert np.array_equal(loaded.masks["all"], valid) == (scene != "venus")
    assert not np.any(loaded.masks["nonocc"] & ~loaded.masks["all"])
    assert not np.any(loaded.masks["disc"] & ~loaded.masks["nonocc"])
    assert loaded.gt_right is not None or scene == "tsukuba"


@pytest.mark.data
def test_real_middlebury_scales(shared_data: Path) -> None:
    root = shared_data / "middlebury-2001-2003"
    teddy = load_scene(root / "teddy")
    raw = np.asarray(Image.open(root / "teddy" / "groundtruth.png").convert("L"))
    assert teddy.gt.max() == pytest.approx(raw.max() / 4) == pytest.approx(52.75)
    assert teddy.gt_right is not None
    assert teddy.gt_right.max() == pytest.approx(211 / 4)
    tsukuba = load_scene(root / "tsukuba")  # palette GT, scale 16, 18-px unknown border
    raw = np.asarray(Image.open(root / "tsukuba" / "groundtruth.png").convert("L"))
    np.testing.assert_array_equal(tsukuba.gt, raw / 16.0)
    assert np.all(tsukuba.gt[:18] == 0)
    venus = load_scene(root / "venus")
    assert venus.gt_right is not None
    assert venus.gt_right.max() == pytest.approx(154 / 8)


@pytest.mark.data
def test_real_kitti(shared_data: Path) -> None:
    folder = shared_data / "kitti-2015" / "000005_10"
    scene = load_scene(folder)
    assert scene.layout == "kitti"
    assert scene.camera is not None
    assert scene.camera.f == pytest.approx(721.5377)
    # (44.85728 + 339.5242) / 721.5377 = 0.53273 m ("≈ 0.54 m")
    assert scene.camera.baseline == pytest.approx(0.5327, abs=5e-4)
    assert scene.camera.doffs == 0
    valid = scene.gt > 0
    assert valid.mean() == pytest.approx(0.196, abs=0.001)
    assert scene.left is not None
    assert scene.left.name == "stereo_left.png"
    q_camera = read_calib(folder / "Q.dat")
    assert q_camera.f == pytest.approx(scene.camera.f)
    assert q_camera.baseline == pytest.approx(scene.camera.baseline, rel=1e-3)
    demo = load_scene(shared_data / "kitti-2015" / "devkit_demo")
    assert demo.layout == "kitti"
    assert demo.camera is None
    assert demo.left is not None
    assert demo.left.name == "image.png"
    assert demo.right is None


@pytest.mark.data
@pytest.mark.parametrize("scene", ["playground", "terrace"])
def test_real_eth3d(shared_data: Path, scene: str) -> None:
    loaded = load_scene(shared_data / "eth3d-two-view" / scene)
    assert loaded.layout == "eth3d"
    assert loaded.camera is not None
    assert loaded.camera.doffs == 0
    assert loaded.camera.baseline == pytest.approx(0.06, abs=0.001)
    assert loaded.masks == {}
    assert np.isinf(loaded.gt).any()


@pytest.mark.data
def test_real_sceneflow(shared_data: Path) -> None:
    folder = shared_data / "sceneflow-flyingthings3d-seq"
    frames = list_frames(folder)
    assert len(frames) == 3
    assert [scene.left.name for scene in frames if scene.left] == [
        "0006.png", "0007.png", "0008.png",
    ]  # fmt: skip
    for scene in frames:
        assert scene.layout == "sceneflow"
        assert scene.camera is not None
        assert scene.camera.f == 1050
        assert scene.camera.baseline == 1
        assert scene.gt.shape == (540, 960)
        assert np.all(np.isfinite(scene.gt) & (scene.gt > 0))  # dense
    np.testing.assert_array_equal(load_scene(folder).gt, frames[0].gt)
    # the 16-bit copy beside it is the same map at scale 256
    png = read_disparity(folder / "Disparity" / "0006_256.png")
    assert np.abs(png - frames[0].gt).max() <= 1 / 256


@pytest.mark.data
def test_real_tartanair(shared_data: Path) -> None:
    scene = load_scene(shared_data / "tartanair-oldtown")
    assert scene.layout == "tartanair"
    assert scene.camera is not None
    assert scene.camera.f == 320
    assert scene.camera.baseline == 0.25
    assert scene.gt.shape == (480, 640)
    assert scene.right is not None
    assert len(list_frames(shared_data / "tartanair-oldtown")) == 1


@pytest.mark.data
def test_real_motorcycle_npz(shared_data: Path) -> None:
    scene = load_scene(shared_data / "middlebury-2014-motorcycle-quarter")
    assert scene.layout == "motorcycle-npz"
    assert scene.gt.shape == (500, 741)
    assert int(np.isinf(scene.gt).sum()) == 27226
    assert scene.camera == Camera(f=994.978, baseline=0.193001, doffs=31.086)


LAYOUTS = {
    "middlebury-2001-2003/tsukuba": "middlebury2001",
    "middlebury-2001-2003/venus": "middlebury2001",
    "middlebury-2001-2003/teddy": "middlebury2001",
    "middlebury-2001-2003/cones": "middlebury2001",
    "middlebury-2014-motorcycle-quarter": "motorcycle-npz",
    "kitti-2015/000005_10": "kitti",
    "kitti-2015/devkit_demo": "kitti",
    "eth3d-two-view/playground": "eth3d",
    "eth3d-two-view/terrace": "eth3d",
    "sceneflow-flyingthings3d-seq": "sceneflow",
    "tartanair-oldtown": "tartanair",
    "kitti-lidar/stereo-rcnn-demo": "kitti-lidar",
    "kitti-lidar/kitti2015-with-velodyne": "kitti-lidar",
    "kitti-raw-drive-0048/2011_09_26/2011_09_26_drive_0048_sync": "kitti-lidar",
    **{f"middeval3-training-Q/{scene}": "middeval3" for scene in MIDDEVAL3_SCENES},
}

BAG_FOLDERS = {"stereo-image-proc": ("offline/test_sip_timing.py", "offline/test_sip_values.py")}
"""Shared folders of recorded bags (not scene layouts), and the tests that read them (from test/)."""


@pytest.mark.data
@pytest.mark.parametrize(("folder", "layout"), sorted(LAYOUTS.items()))
def test_real_layouts(shared_data: Path, folder: str, layout: str) -> None:
    scene = load_scene(shared_data / folder)
    assert scene.layout == layout
    assert scene.gt.dtype == np.float32
    assert scene.gt.ndim == 2
    assert scene.gt.flags.c_contiguous
    assert scene.source == shared_data / folder
    for mask in scene.masks.values():
        assert mask.dtype == bool
        assert mask.shape == scene.gt.shape
    valid = np.isfinite(scene.gt) & (scene.gt > 0)
    assert valid.any()
    assert scene.left is not None
    assert scene.left.is_file()


@pytest.mark.data
def test_real_data_all_folders_covered(shared_data: Path) -> None:
    """Every folder of the shared data is a layout tested above or recorded bags tested elsewhere."""
    tops = {path.name for path in shared_data.iterdir() if path.is_dir()}
    covered = {folder.split("/")[0] for folder in LAYOUTS}
    assert tops == covered | set(BAG_FOLDERS)
    for folder, test_files in BAG_FOLDERS.items():
        for test_file in test_files:
            assert folder in (Path(__file__).parents[1] / test_file).read_text(), test_file
