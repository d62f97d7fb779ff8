"""What the tests of ``dispeval bag`` share: the synthetic drive's methods, its command line,
the same bag in the ROS 1 format, and what "the same database" means.
"""

from __future__ import annotations

import shutil
import sqlite3
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from dispeval_ros.offline.make_bag import (
    CAMERA_FRAME,
    GT_TOPIC,
    LEFT_INFO,
    RIGHT_INFO,
    START_NS,
    disparity_topic,
    synthetic_frames,
)
from dispeval_ros.testbed import driving_setup

METHODS = ("bm_fast", "sgbm", "sgbm_3way")


def method_args() -> list[str]:
    args: list[str] = []
    for name in METHODS:
        args += ["--method", f"{name}={disparity_topic(name)}"]
    return args


def bag_args(bag: Path, out: Path, *extra: str) -> list[str]:
    return [
        "bag",
        str(bag),
        "--gt",
        GT_TOPIC,
        *method_args(),
        "--camera-info",
        LEFT_INFO,
        RIGHT_INFO,
        "--out",
        str(out),
        "--quiet",
        *extra,
    ]


def as_ros1(source: Path, target: Path) -> None:
    """Convert a rosbag2 (sqlite3) bag to a ROS 1 bag, as rosbags' converter does."""
    from rosbags.convert import convert

    convert(
        srcs=[source],
        dst=target,
        dst_storage="sqlite3",
        dst_version=8,
        compress=None,
        compress_mode="file",
        default_typestore=None,
        typestore=None,
        exclude_topics=[],
        include_topics=[],
        exclude_msgtypes=[],
        include_msgtypes=[],
    )


def database_content(folder: Path) -> tuple[list[tuple], ...]:
    """Every table's rows in a canonical order (what 'the same database' means).

    The provenance record is left out: it says how a database was made (which inputs, which
    merge), so it differs by design between an uninterrupted run, a merge and a resume.
    """
    connection = sqlite3.connect(folder / "results.sqlite")
    tables = [
        row[0]
        for row in connection.execute(
            "SELECT name FROM sqlite_master WHERE type='table' AND name != 'provenance' "
            "ORDER BY name"
        )
    ]
    content = tuple(
        sorted(connection.execute(f'SELECT * FROM "{table}"').fetchall(), key=repr)
        for table in tables
    )
    connection.close()
    return content


NOISE = {"rough": 3.0, "fine": 0.3}
"""px of Gaussian noise on the GT: rough is logged first (the fastest), fine after it."""


def fast_rough_bag(
    root: Path, frames: int, noise: Mapping[str, float] = NOISE
) -> tuple[Path, list[str], dict[str, int]]:
    """A synthetic drive bag where the fastest method (``rough``) is the least accurate.

    Returns the bag, the ``dispeval bag`` command line of its methods (``noise``: px of noise
    by method, logged in this order; ``--out`` ROOT/res, every criterion) and each method's
    make-bag order (the lower, the sooner it is logged).
    """
    import numpy as np

    from dispeval_ros.offline.make_bag import estimates_from, synthetic_frames, write_bag
    from dispeval_ros.testbed.methods import default_methods

    drive = list(synthetic_frames(frames, 192, 64, 10.0, seed=4))
    rng = np.random.default_rng(5)
    sources = []
    for name, sigma in noise.items():
        folder = root / name
        folder.mkdir()
        for index, frame in enumerate(drive):
            assert frame.gt is not None
            gt = frame.gt.astype(np.float32)
            noisy = gt + rng.normal(0, sigma, gt.shape).astype(np.float32)
            noisy = np.where(np.isfinite(gt), np.clip(noisy, 0.5, None), np.inf)
            np.save(folder / f"{index:06d}.npy", noisy.astype(np.float32))
        sources.append(estimates_from(name, folder))
    bag = root / "drive"
    summary = write_bag(
        bag, iter(drive), storage="rosbag2-sqlite3", methods=default_methods(192)[:1],
        estimates=sources,
    )  # fmt: skip
    orders = {m: i for i, m in enumerate(summary["methods"])}  # type: ignore[arg-type]
    args = bag_args(bag, root / "res", "--criteria", "all")
    start = args.index("--method")
    args[start : start + 2 * len(METHODS)] = [
        item for name in noise for item in ("--method", f"{name}={disparity_topic(name)}")
    ]
    return bag, args, orders


def quaternion_matrix(translation: Any, rotation: Any) -> np.ndarray:
    """A geometry_msgs translation and unit quaternion as a 4×4, written from the formula."""
    x, y, z, w = rotation.x, rotation.y, rotation.z, rotation.w
    matrix = np.eye(4)
    matrix[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    matrix[:3, 3] = [translation.x, translation.y, translation.z]
    return matrix


NOISY_BIASED = {"noisy": (0.5, 0.0), "biased": (0.0, 1.5)}
"""Per method: px of Gaussian noise and a constant px offset added to the GT."""


def noisy_drive_bag(root: Path, drive: list[Any], noise: Mapping[str, float], seed: int) -> Path:
    """ROOT/drive: a synthetic drive bag (with its exact /tf) whose methods are its GT plus
    Gaussian noise of ``noise[name]`` px drawn anew in each frame (kept in ROOT/<name>/)."""
    from dispeval_ros.offline.make_bag import estimates_from, write_bag
    from dispeval_ros.testbed.methods import default_methods

    rng = np.random.default_rng(seed)
    sources = []
    for name, sigma in noise.items():
        (root / name).mkdir()
        for index, frame in enumerate(drive):
            gt = np.asarray(frame.gt, dtype=np.float32)
            estimate = gt + rng.normal(0, sigma, gt.shape).astype(np.float32) * (sigma > 0)
            np.save(root / name / f"{index:06d}.npy", estimate.astype(np.float32))
        sources.append(estimates_from(name, root / name))
    write_bag(
        root / "drive", iter(drive), storage="rosbag2-sqlite3",
        methods=default_methods(drive[0].gt.shape[1])[:1], estimates=sources,
    )  # fmt: skip
    return root / "drive"


def noisy_biased_drive(root: Path, frames: int, width: int, height: int) -> list[str]:
    """A synthetic drive bag (ROOT/drive, with its exact /tf) of :data:`NOISY_BIASED`'s methods.

    ``noisy`` is the more accurate (smaller errors), ``biased`` the steadier (its bias is no
    temporal noise). Returns the ``dispeval bag --egomotion`` command line (``--out``
    ROOT/res, criterion ``all``; the estimates kept in ROOT/<method>/NNNNNN.npy).
    """
    from dispeval_ros.offline.make_bag import (
        LEFT_IMAGE,
        RIGHT_IMAGE,
        estimates_from,
        synthetic_frames,
        write_bag,
    )
    from dispeval_ros.testbed.methods import default_methods

    drive = list(synthetic_frames(frames, width, height, 10.0, seed=4))
    rng = np.random.default_rng(7)
    sources = []
    for name, (sigma, bias) in NOISY_BIASED.items():
        (root / name).mkdir()
        for index, frame in enumerate(drive):
            assert frame.gt is not None
            gt = frame.gt.astype(np.float32)
            estimate = gt + bias + rng.normal(0, sigma, gt.shape).astype(np.float32)
            estimate = np.where(np.isfinite(gt), np.clip(estimate, 0.5, None), np.inf)
            np.save(root / name / f"{index:06d}.npy", estimate.astype(np.float32))
        sources.append(estimates_from(name, root / name))
    write_bag(
        root / "drive", iter(drive), storage="rosbag2-sqlite3",
        methods=default_methods(width)[:1], estimates=sources,
    )  # fmt: skip
    methods = [f"{name}={disparity_topic(name)}" for name in NOISY_BIASED]
    return [
        "bag", str(root / "drive"), "--gt", GT_TOPIC,
        *(item for method in methods for item in ("--method", method)),
        "--camera-info", LEFT_INFO, RIGHT_INFO, "--left-image", LEFT_IMAGE,
        "--right-image", RIGHT_IMAGE, "--egomotion", "--criteria", "all",
        "--out", str(root / "res"), "--quiet",
    ]  # fmt: skip


def rig_step(earlier: Any, later: Any) -> np.ndarray:
    """The test-bed rig's left camera at ``later`` in its frame at ``earlier`` (4×4).

    Written from the two optical centres, not from the package's ``rig_motion``: the world is
    ``x`` right, ``y`` up, ``z`` forward, the camera ``x`` right, ``y`` down, ``z`` forward,
    and the rig never turns, so the motion is a translation.
    """
    step = np.subtract(later.position, earlier.position)
    motion = np.eye(4)
    motion[:3, 3] = (step[0], -step[1], step[2])
    return motion


def drive_motion_lookup(
    width: int, height: int, seed: int, fps: float = 10.0
) -> Callable[[str, int, int], np.ndarray]:
    """The exact motion of ``make-bag``'s synthetic drive as the pair stage looks it up."""
    _, rig = driving_setup(width, height, fps, seed)

    def motion(camera_frame: str, t0_ns: int, t1_ns: int) -> np.ndarray:
        assert camera_frame == CAMERA_FRAME
        return rig_step(*(rig.at((t - START_NS) / 1e9) for t in (t0_ns, t1_ns)))

    return motion


def numpy_pair_errors(
    root: Path, method: str, frames: int, width: int, height: int, seed: int = 4
) -> list[np.ndarray]:
    """Per pair of consecutive frames of the synthetic drive, TEPE's errors from its definition.

    ``|(E_t − E_t+1) − (D_t − D_t+1)|`` at the same pixel, over the pixels with GT in both
    frames, from the maps saved as ``root/method/NNNNNN.npy`` (what the bag was made of).
    """
    gts = [f.gt for f in synthetic_frames(frames, width, height, 10.0, seed=seed)]
    errors = []
    for index in range(1, frames):
        gt0, gt1 = (np.asarray(g, dtype=np.float64) for g in (gts[index - 1], gts[index]))
        est0 = np.load(root / method / f"{index - 1:06d}.npy").astype(np.float64)
        est1 = np.load(root / method / f"{index:06d}.npy").astype(np.float64)
        with np.errstate(invalid="ignore"):
            both = np.isfinite(gt0) & (gt0 > 0) & np.isfinite(gt1) & (gt1 > 0)
            errors.append(np.abs((est0 - est1) - (gt0 - gt1))[both])
    return errors


def as_written_before(out: Path, old: Path, *tables: str) -> None:
    """Copy the results folder ``out`` to ``old`` as a database written before ``tables`` existed.

    Its report page is removed, so the caller's ``dispeval report`` writes it anew.
    """
    shutil.copytree(out, old)
    connection = sqlite3.connect(old / "results.sqlite")
    for table in tables:
        connection.execute(f"DROP TABLE {table}")
    connection.commit()
    connection.close()
    (old / "report.html").unlink()
