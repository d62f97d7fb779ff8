"""The LiDAR drift between scans re-computed from its definition in plain numpy.

docs/method.md, "LiDAR drift between scans": each point of scan t moved by the camera's
motion into frame t + k, dropped as behind / outside / hidden / missing / missing_target in
that order, and the change of the method's signed error summed per criterion. Written from
the definition, never calling the package's drift code; shared by the ``eval --egomotion``
tests and the ``dispeval bag --egomotion`` ones.
"""

from __future__ import annotations

import numpy as np
from reference import scored_estimate

WINDOW, GAP = 7, 0.1
"""The hidden test: a point of scan t + k within 7×7 px nearer by more than 10 %."""
THRESHOLDS = (0.5, 1.0, 2.0, 4.0)
"""The bad levels a run with δ = 1 scores (δ and the default levels)."""
RANGES = ((0.0, 10.0), (10.0, 30.0), (30.0, np.inf))
"""The depth criteria of a LiDAR reference (``near``, ``mid``, ``far``), metres."""


def numpy_drift(
    scans: tuple[np.ndarray, np.ndarray],
    estimates: tuple[np.ndarray, np.ndarray],
    motion: np.ndarray,
    camera,
    policy: str,
    thresholds: tuple[float, ...] = THRESHOLDS,
    ranges: tuple[tuple[float, float], ...] = RANGES,
) -> np.ndarray:
    """Per criterion (all, then the depth ranges): the sums, by the definition, in numpy.

    ``camera``: f, B (``camera.camera``), cx, cy; ``motion``: the camera at t + k in its
    frame at t (4×4); the hidden test is the 7×7 / 10 % window (:data:`WINDOW`, :data:`GAP`).
    """
    scan, target_scan = scans
    f, cx, cy, fb = camera.camera.f, camera.cx, camera.cy, camera.camera.fb
    rows, columns = np.nonzero(scan > 0)
    d = scan[rows, columns].astype(np.float64)
    z = fb / d
    points = np.stack([z * (columns - cx) / f, z * (rows - cy) / f, z])
    rotation, translation = motion[:3, :3], motion[:3, 3:]
    q = rotation.T @ (points - translation)  # a rigid motion's inverse (the calibration's R
    # are orthonormal to 1e-7 only: np.linalg.inv differs from Rᵀ by that much)
    height, width = scan.shape
    status = np.full(d.size, -1)
    behind = ~(q[2] > 0)
    status[behind] = 1
    with np.errstate(divide="ignore", invalid="ignore"):
        u, v = cx + f * q[0] / q[2], cy + f * q[1] / q[2]
    outside = (status < 0) & ~((u >= 0) & (u <= width - 1) & (v >= 0) & (v <= height - 1))
    status[outside] = 2
    open_ = np.flatnonzero(status < 0)
    with np.errstate(divide="ignore"):
        near_depth = np.where(target_scan > 0, fb / target_scan.astype(np.float64), np.inf)
    col, line = np.floor(u[open_] + 0.5).astype(int), np.floor(v[open_] + 0.5).astype(int)
    hidden = np.zeros(open_.size, bool)
    for dy in range(-(WINDOW // 2), WINDOW // 2 + 1):
        for dx in range(-(WINDOW // 2), WINDOW // 2 + 1):
            r, c = line + dy, col + dx
            ok = (r >= 0) & (r < height) & (c >= 0) & (c < width)
            zr = np.full(open_.size, np.inf)
            zr[ok] = near_depth[r[ok], c[ok]]
            hidden |= zr * (1 + GAP) < q[2, open_]
    status[open_[hidden]] = 3
    (now, now_part), (then, then_part) = (scored_estimate(e, policy) for e in estimates)
    status[(status < 0) & ~now_part[rows, columns]] = 4
    open_ = np.flatnonzero(status < 0)
    x0 = np.minimum(np.floor(u[open_]).astype(int), width - 2)
    y0 = np.minimum(np.floor(v[open_]).astype(int), height - 2)
    ax, ay = u[open_] - x0, v[open_] - y0
    corners = [(y0, x0), (y0, x0 + 1), (y0 + 1, x0), (y0 + 1, x0 + 1)]
    whole = np.all([then_part[y, x] for y, x in corners], axis=0)
    status[open_[~whole]] = 5
    open_ = open_[whole]
    x0, y0, ax, ay = x0[whole], y0[whole], ax[whole], ay[whole]
    corners = [(y0, x0), (y0, x0 + 1), (y0 + 1, x0), (y0 + 1, x0 + 1)]
    a, b, g, h = (then[y, x] for y, x in corners)
    moved = (1 - ay) * ((1 - ax) * a + ax * b) + ay * ((1 - ax) * g + ax * h)
    change = np.full(d.size, np.nan)
    change[open_] = (moved - fb / q[2, open_]) - (now[rows, columns][open_] - d[open_])
    status[status < 0] = 0
    error = now[rows, columns] - d
    sums = []
    for lo, hi in ((0.0, np.inf), *ranges):
        member = (z >= lo) & (z < hi)
        one = member & (status == 0)
        c = change[one]
        sums.append([
            member.sum(), *((member & (status == k)).sum() for k in range(6)),
            np.abs(c).sum(), (c * c).sum(), c.sum(), error[one].sum(),
            *((np.abs(c) > t).sum() for t in thresholds),
        ])  # fmt: skip
    return np.array(sums, dtype=np.float64)
