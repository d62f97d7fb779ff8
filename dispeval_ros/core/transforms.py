"""Rigid transforms and chains of static transforms (the content of ``/tf_static``).

A transform is a 4×4 homogeneous matrix. ``/tf_static`` holds edges ``parent → child``: the
child frame's pose in the parent frame, so the matrix maps points in the child frame into the
parent frame. :class:`TransformTree` composes a chain of such edges, walking them forwards or
backwards, to map points from any frame into any other connected frame.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from dispeval_ros.errors import CalibrationError


def matrix_from_pose(
    translation: Sequence[float] | np.ndarray, quaternion: Sequence[float] | np.ndarray
) -> np.ndarray:
    """The 4×4 matrix of a translation ``(x, y, z)`` and a rotation quaternion ``(qx, qy, qz, qw)``.

    The quaternion is normalised; a zero or non-finite one is an error.
    """
    t = np.asarray(translation, dtype=np.float64).reshape(-1)
    q = np.asarray(quaternion, dtype=np.float64).reshape(-1)
    if t.size != 3 or q.size != 4:
        raise CalibrationError(
            f"a pose is x y z and qx qy qz qw (3 + 4 numbers), got {t.size} + {q.size}"
        )
    norm = float(np.linalg.norm(q))
    if not (np.isfinite(t).all() and math.isfinite(norm)) or norm < 1e-9:
        raise CalibrationError(
            f"a pose needs a finite translation and a non-zero quaternion, got "
            f"t = {t.tolist()}, q = {q.tolist()}"
        )
    x, y, z, w = q / norm
    matrix = np.eye(4)
    matrix[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    matrix[:3, 3] = t
    return matrix


def pose_from_matrix(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Translation ``(x, y, z)`` and unit quaternion ``(qx, qy, qz, qw)`` (``qw ≥ 0``) of a 4×4."""
    rotation = np.asarray(matrix, dtype=np.float64)[:3, :3]
    trace = float(np.trace(rotation))
    # Shepperd's method: divide by the largest of the four candidates (no cancellation).
    candidates = [trace, rotation[0, 0], rotation[1, 1], rotation[2, 2]]
    largest = int(np.argmax(candidates))
    if largest == 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = [
            (rotation[2, 1] - rotation[1, 2]) / s,
            (rotation[0, 2] - rotation[2, 0]) / s,
            (rotation[1, 0] - rotation[0, 1]) / s,
            s / 4.0,
        ]
    else:
        i = largest - 1
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(max(1.0 + rotation[i, i] - rotation[j, j] - rotation[k, k], 1e-300))
        q = [0.0, 0.0, 0.0, (rotation[k, j] - rotation[j, k]) / s]
        q[i] = s / 4.0
        q[j] = (rotation[j, i] + rotation[i, j]) / s
        q[k] = (rotation[k, i] + rotation[i, k]) / s
    quaternion = np.asarray(q, dtype=np.float64)
    quaternion /= np.linalg.norm(quaternion)
    if quaternion[3] < 0:
        quaternion = -quaternion
    return np.asarray(matrix, dtype=np.float64)[:3, 3].copy(), quaternion


def rigid_matrix(values: Sequence[float] | np.ndarray, what: str = "the transform") -> np.ndarray:
    """A 4×4 rigid transform from 16 (4×4), 12 (3×4) or 7 (``x y z qx qy qz qw``) numbers.

    The rotation part must be orthonormal with determinant +1 (to 1e-3): a matrix that is not
    a rigid transform is a calibration mistake, never silently used.
    """
    array = np.asarray(values, dtype=np.float64).reshape(-1)
    if not np.isfinite(array).all():
        raise CalibrationError(f"{what} holds non-finite values")
    if array.size == 7:
        return matrix_from_pose(array[:3], array[3:])
    if array.size not in (12, 16):
        raise CalibrationError(
            f"{what} must be a 4×4 matrix (16 numbers), a 3×4 one (12) or "
            f"'x y z qx qy qz qw' (7), got {array.size} numbers"
        )
    matrix = np.eye(4)
    matrix[: array.size // 4] = array.reshape(-1, 4)
    if not np.allclose(matrix[3], [0, 0, 0, 1], atol=1e-9):
        raise CalibrationError(f"{what}: the last row must be 0 0 0 1, got {matrix[3].tolist()}")
    check_rotation(matrix[:3, :3], f"{what}: the 3×3 rotation part")
    return matrix


def check_rotation(rotation: np.ndarray, what: str) -> np.ndarray:
    """``rotation`` if orthonormal with determinant +1 (to 1e-3), else a one-line refusal.

    One rule for every rotation read from a calibration (extrinsics, CameraInfo ``R``): a
    scaled or sheared matrix would project points to wrong pixels without any error.
    """
    array = np.asarray(rotation, dtype=np.float64)
    if array.shape != (3, 3) or not _is_rotation(array.tolist()):
        raise CalibrationError(f"{what} is not a rotation matrix")
    return rotation


def _is_rotation(rows: list[list[float]]) -> bool:
    """``np.allclose(R·Rᵀ, I, atol=1e-3)`` and ``|det R − 1| < 1e-3`` for finite ``R``.

    In plain floats: for 9 numbers numpy's calls were most of the cost of each /tf sample.
    """
    if not all(math.isfinite(v) for row in rows for v in row):
        return False
    for i in range(3):
        for j in range(i, 3):
            dot = sum(a * b for a, b in zip(rows[i], rows[j], strict=True))
            if abs(dot - (i == j)) > 1e-3 + 1e-5 * (i == j):
                return False
    (a, b, c), (d, e, f), (g, h, k) = rows
    return abs(a * (e * k - f * h) - b * (d * k - f * g) + c * (d * h - e * g) - 1) < 1e-3


def invert_rigid(matrix: np.ndarray) -> np.ndarray:
    """The inverse of a rigid 4×4 transform (``Rᵀ``, ``−Rᵀ·t``)."""
    inverse = np.eye(4)
    rotation = matrix[:3, :3]
    inverse[:3, :3] = rotation.T
    inverse[:3, 3] = -rotation.T @ matrix[:3, 3]
    return inverse


@dataclass(frozen=True)
class StaticTransform:
    """One ``/tf_static`` edge: ``matrix`` maps points in ``child`` into ``parent``."""

    parent: str
    child: str
    matrix: np.ndarray


def _frame(name: str) -> str:
    """Frame ids without a leading slash (``/base_link`` and ``base_link`` are one frame)."""
    return name.lstrip("/")


@dataclass
class TransformTree:
    """The static transforms seen so far; :meth:`lookup` composes chains of them.

    A later edge for the same child replaces the earlier one (as tf2 does for static
    transforms). :meth:`add` replaces the edge table instead of changing it, so lookups in
    other threads always see a consistent table.
    """

    edges: dict[str, StaticTransform] = field(default_factory=dict)

    def add(self, transforms: Iterable[StaticTransform]) -> None:
        """Add or replace edges (keyed by child frame)."""
        edges = dict(self.edges)
        for transform in transforms:
            child = _frame(transform.child)
            edges[child] = StaticTransform(_frame(transform.parent), child, transform.matrix)
        self.edges = edges

    @property
    def frames(self) -> list[str]:
        """Every frame named by an edge, sorted."""
        names = set(self.edges)
        names.update(edge.parent for edge in self.edges.values())
        return sorted(names)

    def lookup(self, target: str, source: str) -> np.ndarray:
        """The 4×4 matrix mapping points in ``source`` into ``target`` (tf2's argument order).

        Raises a :class:`CalibrationError` naming both frames and the frames that exist when
        no chain of edges connects them.
        """
        target, source = _frame(target), _frame(source)
        if target == source:
            return np.eye(4)
        neighbours: dict[str, list[tuple[str, np.ndarray]]] = {}
        edges = self.edges
        for edge in edges.values():
            # Walking child → parent applies the edge, parent → child its inverse.
            neighbours.setdefault(edge.child, []).append((edge.parent, edge.matrix))
            neighbours.setdefault(edge.parent, []).append((edge.child, invert_rigid(edge.matrix)))
        # Breadth-first from source; each frame holds source → frame.
        found: dict[str, np.ndarray] = {source: np.eye(4)}
        queue = deque([source])
        while queue:
            frame = queue.popleft()
            for other, step in neighbours.get(frame, []):
                if other not in found:
                    found[other] = step @ found[frame]
                    if other == target:
                        return found[other]
                    queue.append(other)
        known = ", ".join(self.frames) or "none (no /tf_static transform received)"
        raise CalibrationError(
            f"no chain of static transforms connects the cloud frame '{source}' to the camera "
            f"frame '{target}'; frames in /tf_static: {known}"
        )
