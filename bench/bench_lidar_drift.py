"""LiDAR drift between scans: the compiled pass against plain numpy, per 1242×375 pair.

Prints timings and ratios only (machines are noisy: nothing here is asserted). Run:

    python bench/bench_lidar_drift.py [--repeat N]

Pair: frames 0 → 1 of the shared KITTI raw drive (``kitti-raw-drive-0048`` under
``DISPEVAL_DATA`` or ``../shared/data``) as ``eval --scene DRIVE --egomotion`` scores it: the
projected scans (z-buffer, 7×7 / 10 % parallax filter), the oxts motion, OpenCV SGBM's
estimates of both frames, criteria ``all`` + ``depth`` (0–10, 10–30, 30+ m), thresholds 0.5,
1, 2, 4. Without the data (said in the output): two frames of the test-bed drive at the same
size, 0.1 s apart, its 64-beam scans projected by ``project_cloud`` and its exact motion.

The numpy baseline is written here from the definition (docs/method.md, "LiDAR drift between
scans"): whole-array steps, the hidden test by the window's nearest depth (49 gathers), one
boolean mask per criterion. It reads the estimates as (value, valid) maps: numpy codes the
``thesis`` and ``ignore`` policies itself and takes ``interpolate``'s filled values from
``coded_estimate`` (the KITTI interpolation is not the drift's definition). Both must give the
same counts and sums (to 1e-9) under every policy before anything is timed, and numpy's own
interpolation (``numpy_interpolation``, written from docs/method.md) must equal
``coded_estimate``'s bit for bit. Rows: the pass per pair; ``coded_estimate`` per frame (numpy:
``np.where`` for ``thesis``/``ignore``, ``numpy_interpolation`` for ``interpolate``); per frame
of a stream, where each frame is coded once and starts one pair, against numpy doing the same
(its pass and the same policy's coding).

Every case is timed twice per round, the cases in turn (a slow phase of a shared machine hits
all of them): warm, just after the same call (as the other benches time), and cold, just after
a 64 MB read. Printed are the best and the median of the rounds' CPU times (``process_time``;
a sum of two rows: the sums of their bests and of their medians) and the ratio of the best warm
times. The process is pinned to one core, the kernels are serial; the load average at the
start is printed.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from dispeval_ros.core import Evaluator
from dispeval_ros.core.criteria import LIDAR_DEPTH_RANGES
from dispeval_ros.core.egomotion import PinholeCamera, camera_motion
from dispeval_ros.core.lidar_drift import (
    BASE_COLUMNS,
    STATUS_NAMES,
    DriftOptions,
    coded_estimate,
    lidar_drift,
)
from dispeval_ros.core.projection import CloudFilter, project_cloud, rectified_projection
from dispeval_ros.testbed import default_methods, driving_setup, driving_world_at, render_stereo
from dispeval_ros.testbed.lidar import LidarModel, lidar_to_camera, simulate_scan
from dispeval_ros.testbed.scene import KITTI_HEIGHT, KITTI_WIDTH

DATA = Path(
    os.environ.get("DISPEVAL_DATA") or Path(__file__).resolve().parents[2] / "shared" / "data"
)
DRIVE = DATA / "kitti-raw-drive-0048" / "2011_09_26" / "2011_09_26_drive_0048_sync"
THRESHOLDS = (0.5, 1.0, 2.0, 4.0)
POLICIES = ("interpolate", "thesis", "ignore")

Pair = tuple[str, tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], np.ndarray]
"""(what it is, the scans at t and t + 1, SGBM's estimates there, the motion) and a camera."""


def kitti_pair() -> tuple[Pair, PinholeCamera]:
    """Frames 0 → 1 of the shared drive, read as ``eval`` reads them."""
    from dispeval_ros.io.kitti_raw import camera_poses, open_drive
    from dispeval_ros.io.scenes import list_frames

    scenes = list_frames(DRIVE)[:2]
    drive = open_drive(DRIVE)
    _, cx, cy = drive.calibration.ros_view()
    poses = camera_poses(drive)
    sgbm = next(m for m in default_methods(KITTI_WIDTH) if m.name == "sgbm")
    estimates = [
        sgbm.compute(*(cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in (s.left, s.right)))
        for s in scenes
    ]
    assert scenes[0].camera is not None
    return (
        f"KITTI raw {DRIVE.name}, frames {scenes[0].frame} → {scenes[1].frame}",
        (scenes[0].gt, scenes[1].gt),
        (estimates[0], estimates[1]),
        camera_motion(poses[0], poses[1]),
    ), PinholeCamera(scenes[0].camera, cx, cy)


def synthetic_pair() -> tuple[Pair, PinholeCamera]:
    """Two frames of the test-bed drive, 0.1 s apart: rendered, scanned, exact motion."""
    world, rig = driving_setup(KITTI_WIDTH, KITTI_HEIGHT, 10.0, 0)
    model = LidarModel(beams=64, azimuth_step=0.165)
    k = np.array([[rig.f, 0, rig.cx, 0], [0, rig.f, rig.cy, 0], [0, 0, 1, 0]])
    sgbm = next(m for m in default_methods(KITTI_WIDTH) if m.name == "sgbm")
    scans, estimates, positions = [], [], []
    for index in range(2):
        world_t, rig_t = driving_world_at(world, rig, index / 10.0)
        frame = render_stereo(world_t, rig_t, stamp=index / 10.0, noise_seed=[0, index])
        matrix = rectified_projection(lidar_to_camera(rig_t, model), np.eye(3), k)
        points = simulate_scan(world_t, rig_t, model)
        shape = (KITTI_HEIGHT, KITTI_WIDTH)
        scans.append(project_cloud(points, matrix, shape, rig.camera, CloudFilter()).disparity)
        estimates.append(sgbm.compute(frame.left, frame.right))
        positions.append(rig_t.position)
    motion = np.eye(4)
    motion[2, 3] = positions[1][2] - positions[0][2]  # the rig drives along its optical axis
    return (
        "synthetic test-bed drive (no KITTI raw drive found), frames 0 → 1",
        (scans[0], scans[1]),
        (estimates[0], estimates[1]),
        motion,
    ), PinholeCamera(rig.camera, rig.cx, rig.cy)


def numpy_coding(estimate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(value, valid) of an estimate under ``thesis`` / ``ignore``: a hole is 0, not valid."""
    valid = np.isfinite(estimate) & (estimate > 0)
    return np.where(valid, estimate, np.float32(0)), valid


def numpy_interpolation(estimate: np.ndarray) -> np.ndarray:
    """An estimate coded under ``interpolate``, written from docs/method.md (validity in the sign).

    KITTI's background interpolation: along each row a gap between two valid estimates takes
    the smaller neighbour, a leading gap the first valid value, a trailing gap the last; rows
    above the first and below the last row with a valid value copy that row; what is still
    missing is 0. Valid values stay positive, filled ones are negated.
    """
    values = np.asarray(estimate, np.float32)
    valid = np.isfinite(values) & (values > 0)
    height, width = values.shape
    columns = np.arange(width)
    before = np.maximum.accumulate(np.where(valid, columns, -1), axis=1)
    after = np.minimum.accumulate(np.where(valid, columns, width)[:, ::-1], axis=1)[:, ::-1]
    rows = np.arange(height)[:, None]
    left = np.where(before >= 0, values[rows, np.clip(before, 0, width - 1)], np.nan)
    right = np.where(after < width, values[rows, np.clip(after, 0, width - 1)], np.nan)
    filled = np.where(
        np.isnan(left), right, np.where(np.isnan(right), left, np.minimum(left, right))
    )
    with_values = valid.any(axis=1)
    if with_values.any():
        first, last = np.argmax(with_values), height - 1 - np.argmax(with_values[::-1])
        filled[:first] = filled[first]
        filled[last + 1 :] = filled[last]
    return np.where(valid, values, -np.nan_to_num(filled, nan=0.0)).astype(np.float32)


def numpy_drift(
    scans: tuple[np.ndarray, np.ndarray],
    maps: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    motion: np.ndarray,
    camera: PinholeCamera,
    masks: dict[str, np.ndarray],
    ignore: bool,
    window: int = 7,
    gap: float = 0.1,
) -> np.ndarray:
    """The sums of :data:`BASE_COLUMNS` and the bad counts, one row per criterion, by numpy."""
    (value, valid), (value_next, valid_next) = maps
    scan, scan_next = scans
    f, cx, cy, fb, doffs = camera.geometry()
    height, width = scan.shape
    ys, xs = np.nonzero(scan > 0)
    d = scan[ys, xs].astype(np.float64)
    rotation, translation = motion[:3, :3], motion[:3, 3]
    back = np.column_stack([rotation.T, -rotation.T @ translation])  # motion⁻¹, rigid
    with np.errstate(divide="ignore", invalid="ignore"):
        z = fb / (d + doffs)
        px, py = z * (xs - cx) / f, z * (ys - cy) / f
        qx, qy, qz = (r[0] * px + r[1] * py + r[2] * z + r[3] for r in back)
        u, v = cx + f * qx / qz, cy + f * qy / qz
    status = np.full(d.size, -1, np.int64)
    status[~((d + doffs > 0) & (qz > 0))] = 1  # behind
    inside = (u >= 0) & (u <= width - 1) & (v >= 0) & (v <= height - 1)
    status[(status < 0) & ~inside] = 2  # outside
    open_ = np.flatnonzero(status < 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        point = (scan_next > 0) & (scan_next + doffs > 0)
        depth_next = np.where(point, fb / (scan_next.astype(np.float64) + doffs), np.inf)
    half = window // 2
    padded = np.pad(depth_next, half, constant_values=np.inf)
    line = np.floor(v[open_] + 0.5).astype(np.int64)
    col = np.floor(u[open_] + 0.5).astype(np.int64)
    nearest = np.full(open_.size, np.inf)
    for dy in range(window):
        for dx in range(window):
            np.minimum(nearest, padded[line + dy, col + dx], out=nearest)
    status[open_[nearest * (1 + gap) < qz[open_]]] = 3  # hidden
    if ignore:
        status[(status < 0) & ~valid[ys, xs]] = 4  # missing
    left = np.flatnonzero(status < 0)
    x0 = np.minimum(np.floor(u[left]).astype(np.int64), width - 2)
    y0 = np.minimum(np.floor(v[left]).astype(np.int64), height - 2)
    if ignore:
        support = valid_next[y0, x0] & valid_next[y0, x0 + 1]
        support &= valid_next[y0 + 1, x0] & valid_next[y0 + 1, x0 + 1]
        status[left[~support]] = 5  # missing_target
        left, x0, y0 = left[support], x0[support], y0[support]
    ax, ay = u[left] - x0, v[left] - y0
    top = (1 - ax) * value_next[y0, x0] + ax * value_next[y0, x0 + 1]
    bottom = (1 - ax) * value_next[y0 + 1, x0] + ax * value_next[y0 + 1, x0 + 1]
    error = value[ys[left], xs[left]] - d[left]
    change = ((1 - ay) * top + ay * bottom - (fb / qz[left] - doffs)) - error
    status[left] = 0
    counted = np.zeros(d.size, bool)
    counted[left] = True
    terms = np.zeros((4 + len(THRESHOLDS), d.size))
    terms[:, left] = [abs(change), change * change, change, error,
                      *(abs(change) > t for t in THRESHOLDS)]  # fmt: skip
    rows = []
    for mask in masks.values():
        member = mask[ys, xs]
        statuses = np.bincount(status[member], minlength=6)
        rows.append([member.sum(), *statuses, *terms[:, member & counted].sum(axis=1)])
    return np.array(rows, dtype=np.float64)


SWEEP = np.ones(8 << 20)
"""64 MB read before a cold call: the pair's maps (7.5 MB) leave the core's caches."""


def rounds(
    cases: dict[str, Callable[[], object]], repeat: int
) -> dict[str, tuple[float, float, float, float]]:
    """Best and median CPU ms of each case, warm then cold, over ``repeat`` rounds.

    Warm: just after the same call (its maps in the caches, as in the other benches); cold:
    just after :data:`SWEEP` is read (as a stream's next pair comes after other work).
    """

    def once(run: Callable[[], object]) -> float:
        start = time.process_time()
        run()
        return 1e3 * (time.process_time() - start)

    samples: dict[str, tuple[list[float], list[float]]] = {name: ([], []) for name in cases}
    for _ in range(repeat):
        for name, run in cases.items():
            warm, cold = samples[name]
            run()
            warm.append(once(run))
            SWEEP.sum()
            cold.append(once(run))
    return {
        name: (min(w), float(np.median(w)), min(c), float(np.median(c)))
        for name, (w, c) in samples.items()
    }


def main() -> None:
    """Check numpy and the kernel agree on the pair, then time them."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--repeat", type=int, default=30, help="timed rounds")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    load = " ".join(f"{value:.2f}" for value in os.getloadavg())
    (what, scans, estimates, motion), camera = kitti_pair() if DRIVE.is_dir() else synthetic_pair()
    evaluator = Evaluator(("all", "depth"), ("mae",), depth_ranges=LIDAR_DEPTH_RANGES)
    partition = evaluator.reference(scans[0], camera.camera).partition
    masks = {name: partition.mask(name) for name in partition.criteria}
    options = {p: DriftOptions(missing=p, thresholds=THRESHOLDS) for p in POLICIES}
    coded = {p: [coded_estimate(e, p) for e in estimates] for p in POLICIES}
    plain = [numpy_coding(e) for e in estimates]

    def ours(policy: str) -> np.ndarray:
        return lidar_drift(*scans, *coded[policy], motion, camera, partition, options[policy]).sums

    def theirs(policy: str) -> np.ndarray:
        if policy == "interpolate":
            filled = [(np.abs(c), c > 0) for c in coded[policy]]
            return numpy_drift(scans, (filled[0], filled[1]), motion, camera, masks, False)
        return numpy_drift(scans, (plain[0], plain[1]), motion, camera, masks, policy == "ignore")

    first = 1 + len(STATUS_NAMES)  # n and the statuses, then the sums, then the bad counts
    counts = [*range(first), *range(len(BASE_COLUMNS), len(BASE_COLUMNS) + len(THRESHOLDS))]
    for policy in POLICIES:
        a, b = ours(policy), theirs(policy)
        if not (
            np.array_equal(a[:, counts], b[:, counts])
            and np.allclose(
                a[:, first : len(BASE_COLUMNS)],
                b[:, first : len(BASE_COLUMNS)],
                rtol=1e-9,
                atol=1e-9,
            )
        ):
            raise SystemExit(f"the compiled and numpy drift sums differ under {policy}")
        if policy != "interpolate" and not all(
            np.array_equal(np.abs(c), v) and np.array_equal(c > 0, ok)
            for c, (v, ok) in zip(coded[policy], plain, strict=True)
        ):
            raise SystemExit(f"coded_estimate and numpy's coding differ under {policy}")
    if not all(
        np.array_equal(c, numpy_interpolation(e))
        for c, e in zip(coded["interpolate"], estimates, strict=True)
    ):
        raise SystemExit("coded_estimate and numpy's interpolation differ")

    summary = lidar_drift(*scans, *coded["interpolate"], motion, camera, partition).summary("all")
    print(f"dispeval_ros LiDAR drift benchmark (one core; load average {load} at the start)")
    print(
        f"\n{what}, SGBM: {summary['n']:.0f} points of the scan at t, {summary['n_drift']:.0f} "
        f"counted ({summary['n_outside']:.0f} outside, {summary['n_hidden']:.0f} hidden, "
        f"{summary['n_behind']:.0f} behind), mean drift {summary['mean']:.3f} px (interpolate); "
        f"{len(partition.criteria)} criteria; numpy and compiled sums agree under "
        f"{', '.join(POLICIES)}"
    )
    cases: dict[str, Callable[[], object]] = {
        "numpy": lambda: theirs("thesis"),
        "numpy coding": lambda: numpy_coding(estimates[0]),
        "numpy interpolation": lambda: numpy_interpolation(estimates[0]),
        **{f"pass {p}": (lambda p=p: ours(p)) for p in POLICIES},
        **{f"coded {p}": (lambda p=p: coded_estimate(estimates[0], p)) for p in POLICIES},
    }
    times = rounds(cases, args.repeat)
    base, base_coding = times["numpy"][0], times["numpy coding"][0]
    print(
        f"ms, best / median of {args.repeat} rounds, warm (after the same call) and cold "
        "(after a 64 MB read); the ratio: numpy's best warm time / the best warm time"
    )
    print(f"  {'':<44} {'warm':>15} {'cold':>15}")

    def row(label: str, values: tuple[float, ...], reference: float) -> None:
        warm, cold = values[:2], values[2:]
        print(
            f"  {label:<44} {warm[0]:6.2f} / {warm[1]:6.2f} {cold[0]:6.2f} / {cold[1]:6.2f}"
            f"   {reference / warm[0]:5.1f}×"
        )

    print("per pair")
    row("numpy, thesis (the baseline)", times["numpy"], base)
    for policy in POLICIES:
        row(f"lidar_drift, {policy}", times[f"pass {policy}"], base)
    coding = {p: "numpy interpolation" if p == "interpolate" else "numpy coding" for p in POLICIES}
    print("per frame (each frame's estimate coded once, used by both its pairs)")
    row("numpy coding, thesis (np.where)", times["numpy coding"], base_coding)
    row("numpy coding, interpolate", times["numpy interpolation"], times[coding["interpolate"]][0])
    for policy in POLICIES:
        row(f"coded_estimate, {policy}", times[f"coded {policy}"], times[coding[policy]][0])
    print("per frame of a stream: one pair + one coding (numpy: the same policy's coding)")
    for policy in POLICIES:
        reference = base + times[coding[policy]][0]
        numpy_total = tuple(np.add(times["numpy"], times[coding[policy]]))
        row(f"numpy, {policy}", numpy_total, reference)
        total = tuple(np.add(times[f"pass {policy}"], times[f"coded {policy}"]))
        row(f"lidar_drift + coded_estimate, {policy}", total, reference)


if __name__ == "__main__":
    main()
