"""Dynamic transforms over time (``/tf``) beside the static tree: tf2's lookup semantics.

A robot publishes its ego-motion on ``/tf`` (e.g. ``odom → base_link`` at its odometry's rate)
and the sensor mounts once on ``/tf_static``. :class:`TransformHistory` keeps each dynamic
edge's samples in stamp order and answers lookups the way tf2's ``BufferCore`` does: each
dynamic edge is interpolated between the two samples around the stamp (translation linearly,
rotation by slerp on the shorter arc), never extrapolated; static edges hold at every stamp.

Where tf2 warns and drops, this refuses with one line, so nothing is silently lost or
guessed: a stamp outside an edge's samples (:class:`ExtrapolationError`, saying by how
much), a sample older than the cache window, a frame given two parents, a loop
(:class:`TransformDataError`), a chain that does not connect two frames
(:class:`TransformChainError`, naming both and the frames known). Samples that arrive out of
order are inserted in order (as tf2 does); a repeated stamp replaces the earlier sample (tf2
would keep both and use the first). A stamp is a stamp: 0 does not mean "latest" as in tf2.
"""

from __future__ import annotations

import bisect
import math
import threading
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from dispeval_ros.core.transforms import (
    StaticTransform,
    TransformTree,
    check_rotation,
    invert_rigid,
    pose_from_matrix,
)
from dispeval_ros.errors import (
    CalibrationError,
    ExtrapolationError,
    TransformChainError,
    TransformDataError,
)

__all__ = [
    "DEFAULT_CACHE_NS",
    "DEFAULT_FIXED_FRAME",
    "EdgeSpan",
    "ExtrapolationError",
    "TransformChainError",
    "TransformDataError",
    "TransformHistory",
    "format_stamp",
]

_Pose = tuple[float, ...]
"""``x y z qx qy qz qw``: a translation and a unit quaternion."""

DEFAULT_CACHE_NS = 10_000_000_000
"""How long each dynamic edge keeps its samples behind its newest one (tf2's default: 10 s)."""
DEFAULT_FIXED_FRAME = "odom"
"""REP 105's continuous world frame: the camera's motion goes through it when it is above it."""


def format_stamp(stamp_ns: int) -> str:
    """A stamp in seconds with every nanosecond (``1700000000.100000000 s``): no float rounding."""
    sign = "-" if stamp_ns < 0 else ""
    whole, part = divmod(abs(int(stamp_ns)), 1_000_000_000)
    return f"{sign}{whole}.{part:09d} s"


def _ms(delta_ns: int) -> str:
    """A stamp difference: in ms to the µs, or in ns below a millisecond (never "0.000 ms")."""
    size = abs(delta_ns)
    return f"{size / 1e6:.3f} ms" if size >= 1_000_000 else f"{size} ns"


def _frame(name: str) -> str:
    """Frame ids without a leading slash (as :class:`TransformTree` keys them)."""
    return name.lstrip("/")


@dataclass(frozen=True)
class EdgeSpan:
    """What one dynamic edge holds: its frames, how many samples and their first/last stamps.

    ``late``: samples that arrived after one with a later stamp (put in order; a publisher's or
    recorder's reordering shows here); ``replaced``: samples that replaced one of the same stamp.
    """

    parent: str
    child: str
    samples: int
    first_ns: int
    last_ns: int
    late: int = 0
    replaced: int = 0


@dataclass
class _Edge:
    """One dynamic edge's samples in stamp order: the matrix given, and ``x y z qx qy qz qw``.

    The pose (translation and quaternion) is worked out when an interpolation first needs it:
    most samples of a fast /tf are never between the two of a lookup.
    """

    parent: str
    child: str
    stamps: list[int] = field(default_factory=list)
    matrices: list[np.ndarray] = field(default_factory=list)
    poses: list[_Pose | None] = field(default_factory=list)
    pruned: bool = False
    late: int = 0
    replaced: int = 0

    @property
    def name(self) -> str:
        return f"{self.parent} → {self.child}"

    def insert(self, stamp: int, matrix: np.ndarray, cache_ns: int) -> None:
        """Insert in stamp order (a repeated stamp replaces), then drop what left the window."""
        stamps = self.stamps
        if stamps and stamp < stamps[-1] - cache_ns:
            raise TransformDataError(
                f"/tf {self.name} at {format_stamp(stamp)} is {_ms(stamps[-1] - stamp)} older "
                f"than its newest sample ({format_stamp(stamps[-1])}); the cache keeps "
                f"{cache_ns / 1e9:g} s"
            )
        index = bisect.bisect_left(stamps, stamp)
        if index < len(stamps) and stamps[index] == stamp:
            self.matrices[index], self.poses[index] = matrix, None
            self.replaced += 1
            return
        if index < len(stamps):
            self.late += 1
        stamps.insert(index, stamp)
        self.matrices.insert(index, matrix)
        self.poses.insert(index, None)
        drop = bisect.bisect_left(stamps, stamps[-1] - cache_ns)
        if drop:
            del stamps[:drop], self.matrices[:drop], self.poses[:drop]
            self.pruned = True

    def _pose(self, index: int) -> _Pose:
        pose = self.poses[index]
        if pose is None:
            translation, quaternion = pose_from_matrix(self.matrices[index])
            pose = self.poses[index] = tuple(float(v) for v in (*translation, *quaternion))
        return pose

    def at(self, stamp: int) -> np.ndarray:
        """The 4×4 matrix (child → parent) at ``stamp``, interpolated; never extrapolated."""
        stamps = self.stamps
        index = bisect.bisect_left(stamps, stamp)
        if index < len(stamps) and stamps[index] == stamp:
            return self.matrices[index]  # the matrix as given: no quaternion round trip
        if index == 0 or index == len(stamps):
            raise self._outside(stamp)
        before, after = stamps[index - 1], stamps[index]
        ratio = (stamp - before) / (after - before)
        return _matrix(_interpolate(self._pose(index - 1), self._pose(index), ratio))

    def _outside(self, stamp: int) -> ExtrapolationError:
        first, last = self.stamps[0], self.stamps[-1]
        future = stamp > last
        if future:
            where = f"after its newest sample ({format_stamp(last)}) by {_ms(stamp - last)}"
        else:
            where = f"before its oldest sample ({format_stamp(first)}) by {_ms(first - stamp)}"
            if self.pruned:
                where += " (older samples left the cache window)"
        return ExtrapolationError(
            f"/tf {self.name} has no sample around {format_stamp(stamp)}: the stamp is {where}; "
            f"{len(self.stamps)} sample(s) span {format_stamp(first)} – {format_stamp(last)} "
            "and a transform is never extrapolated",
            edge=(self.parent, self.child),
            stamp_ns=stamp,
            future=future,
        )


def _interpolate(first: _Pose, second: _Pose, ratio: float) -> _Pose:
    """Linear translation and slerp rotation (the shorter arc) at ``ratio`` ∈ (0, 1).

    Plain floats: for 7 numbers Python's math is several times faster than numpy's calls.
    """
    x, y, z = (a + ratio * (b - a) for a, b in zip(first[:3], second[:3], strict=True))
    q0, q1 = first[3:], second[3:]
    dot = sum(a * b for a, b in zip(q0, q1, strict=True))
    sign = 1.0
    if dot < 0:  # q and −q are one rotation: take the shorter way
        sign, dot = -1.0, -dot
    if dot > 1 - 1e-12:
        w0, w1 = 1 - ratio, ratio
    else:
        angle = math.acos(min(dot, 1.0))
        w0 = math.sin((1 - ratio) * angle) / math.sin(angle)
        w1 = math.sin(ratio * angle) / math.sin(angle)
    q = [w0 * a + sign * w1 * b for a, b in zip(q0, q1, strict=True)]
    norm = math.sqrt(sum(v * v for v in q))
    return (x, y, z, *(v / norm for v in q))


def _matrix(pose: _Pose) -> np.ndarray:
    """The 4×4 of ``x y z`` and a unit quaternion (as :func:`matrix_from_pose`, unchecked)."""
    tx, ty, tz, x, y, z, w = pose
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w), tx],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w), ty],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y), tz],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


@dataclass(frozen=True)
class _Path:
    """A cached chain: the edges (child frames) up from ``source`` and up from ``target``."""

    up_source: tuple[str, ...]
    up_target: tuple[str, ...]


class TransformHistory:
    """Dynamic ``/tf`` edges over time plus the static tree; tf2's lookup semantics.

    Thread-safe: the live node adds from its subscription while the pair stage looks up.
    Chains are cached until an edge joins or changes parent, so a lookup costs one
    interpolation and a few 4×4 products per edge.
    """

    def __init__(self, static: TransformTree | None = None, cache_ns: int = DEFAULT_CACHE_NS):
        if (
            isinstance(cache_ns, bool)
            or not isinstance(cache_ns, (int, np.integer))
            or cache_ns <= 0
        ):
            raise TransformDataError(f"the /tf cache window must be > 0 ns, got {cache_ns!r}")
        self.static = static if static is not None else TransformTree()
        self.cache_ns = int(cache_ns)
        self._edges: dict[str, _Edge] = {}
        self._lock = threading.RLock()
        self._paths: dict[tuple[str, str], _Path] = {}
        self._seen: tuple[object, int] = (None, 0)
        """The static edge table (replaced, never changed, on add) and dynamic version cached."""
        self._version = 0

    # -- adding ------------------------------------------------------------------------------

    def add_static(self, transforms: Iterable[StaticTransform]) -> None:
        """Add ``/tf_static`` edges; one that names a child already on ``/tf`` is refused.

        The other edges are kept; the refusal is one line naming the first conflict.
        """
        kept, problems = [], []
        with self._lock:
            for transform in transforms:
                parent, child = _frame(transform.parent), _frame(transform.child)
                try:
                    self._check_edge(parent, child, static=True)
                    rotation = np.asarray(transform.matrix)[:3, :3]
                    check_rotation(rotation, f"/tf_static {parent} → {child}: the rotation")
                except (TransformDataError, CalibrationError) as error:
                    problems.append(str(error))
                    continue
                matrix = np.array(transform.matrix, dtype=np.float64)  # never the caller's
                kept.append(StaticTransform(parent, child, matrix))
            self.static.add(kept)
        _raise_first(problems)

    def add(self, stamp_ns: int, transform: StaticTransform) -> None:
        """Add one ``/tf`` sample: ``transform`` (parent → child) at ``stamp_ns``."""
        parent, child = _frame(transform.parent), _frame(transform.child)
        name = f"/tf {parent} → {child}"
        matrix = np.asarray(transform.matrix, dtype=np.float64)
        if matrix.shape != (4, 4) or not np.isfinite(matrix).all():
            raise TransformDataError(f"{name} at {format_stamp(stamp_ns)}: not a finite 4×4")
        check_rotation(matrix[:3, :3], f"{name} at {format_stamp(stamp_ns)}: the rotation")
        with self._lock:
            edge = self._edges.get(child)
            if edge is None:
                self._check_edge(parent, child, static=False)
                edge = _Edge(parent, child)
                self._edges[child] = edge
                self._version += 1
            elif edge.parent != parent:
                raise TransformDataError(
                    f"{name} at {format_stamp(stamp_ns)}: frame '{child}' already has the parent "
                    f"'{edge.parent}' on /tf; a frame has one parent"
                )
            edge.insert(int(stamp_ns), matrix.copy(), self.cache_ns)

    def extend(self, samples: Iterable[tuple[int, StaticTransform]]) -> list[str]:
        """Add every sample that can be added; the one-line problems of the others."""
        problems = []
        for stamp, transform in samples:
            try:
                self.add(stamp, transform)
            except (TransformDataError, CalibrationError) as error:
                problems.append(str(error))
        return problems

    def _check_edge(self, parent: str, child: str, *, static: bool) -> None:
        """Refuse a self-edge, a second parent (across /tf and /tf_static) and a loop."""
        source = "/tf_static" if static else "/tf"
        if not child or not parent or parent == child:
            raise TransformDataError(
                f"{source} '{parent}' → '{child}': not an edge between two named frames"
            )
        if static and child in self._edges:
            raise TransformDataError(
                f"/tf_static {parent} → {child}: frame '{child}' already has the parent "
                f"'{self._edges[child].parent}' on /tf; a frame has one parent"
            )
        if not static and child in self.static.edges:
            raise TransformDataError(
                f"/tf {parent} → {child}: frame '{child}' already has the parent "
                f"'{self.static.edges[child].parent}' on /tf_static; a frame has one parent"
            )
        if child in self._ancestors(parent):
            raise TransformDataError(
                f"{source} {parent} → {child}: '{child}' is above '{parent}' already, "
                "so the edge would make a loop"
            )

    # -- the tree ------------------------------------------------------------------------------

    def _parent(self, frame: str) -> str | None:
        edge = self._edges.get(frame)
        if edge is not None:
            return edge.parent
        static = self.static.edges.get(frame)
        return static.parent if static is not None else None

    def _ancestors(self, frame: str) -> list[str]:
        """``frame`` and every frame above it, up to its root."""
        chain = [frame]
        parent = self._parent(frame)
        while parent is not None:
            if parent in chain:  # only static edges can loop (each /tf edge is checked)
                raise TransformDataError(
                    f"/tf_static edges make a loop: {' → '.join(reversed([*chain, parent]))}"
                )
            chain.append(parent)
            parent = self._parent(parent)
        return chain

    @property
    def frames(self) -> list[str]:
        """Every frame named by a ``/tf`` or ``/tf_static`` edge, sorted."""
        with self._lock:
            names = set(self.static.frames)
            for edge in self._edges.values():
                names.update((edge.parent, edge.child))
            return sorted(names)

    def spans(self) -> list[EdgeSpan]:
        """Each dynamic edge's sample count and first/last stamp (for ``info``), by child."""
        with self._lock:
            return [
                EdgeSpan(
                    e.parent, e.child, len(e.stamps), e.stamps[0], e.stamps[-1], e.late, e.replaced
                )
                for _, e in sorted(self._edges.items())
                if e.stamps
            ]

    def _path(self, target: str, source: str) -> _Path:
        static, version = self._seen
        if static is not self.static.edges or version != self._version:
            self._paths, self._seen = {}, (self.static.edges, self._version)
        path = self._paths.get((target, source))
        if path is None:
            up_source, up_target = self._ancestors(source), self._ancestors(target)
            common = set(up_source) & set(up_target)
            if not common:
                raise self._no_chain(target, source)
            # The lowest common frame: the first of source's chain that target's chain holds.
            meet = next(frame for frame in up_source if frame in common)
            path = _Path(
                tuple(up_source[: up_source.index(meet)]),
                tuple(up_target[: up_target.index(meet)]),
            )
            self._paths[(target, source)] = path
        return path

    def _no_chain(self, target: str, source: str) -> TransformChainError:
        known = self.frames
        if not known:
            return TransformChainError(
                f"no transform connects '{source}' to '{target}': no /tf or /tf_static "
                "transform received"
            )
        return TransformChainError(
            f"no chain of /tf and /tf_static transforms connects '{source}' to '{target}'; "
            f"frames known: {', '.join(known)}"
        )

    def _up(self, edges: tuple[str, ...], stamp: int) -> np.ndarray:
        """The product of the edges from a frame up to the meeting frame, at ``stamp``."""
        matrix: np.ndarray | None = None
        for child in edges:
            dynamic = self._edges.get(child)
            step = dynamic.at(stamp) if dynamic is not None else self.static.edges[child].matrix
            matrix = step.copy() if matrix is None else step @ matrix  # never a stored array
        return np.eye(4) if matrix is None else matrix

    # -- lookups -------------------------------------------------------------------------------

    def lookup(self, target: str, source: str, stamp_ns: int) -> np.ndarray:
        """The 4×4 matrix mapping points in ``source`` into ``target`` at ``stamp_ns`` (tf2 order).

        Raises :class:`TransformChainError` when no chain connects them and
        :class:`ExtrapolationError` when a dynamic edge of the chain has no samples around
        the stamp.
        """
        target, source = _frame(target), _frame(source)
        if target == source:
            return np.eye(4)
        with self._lock:
            path = self._path(target, source)  # an unknown frame meets no other: no chain
            stamp = int(stamp_ns)
            to_meet = self._up(path.up_source, stamp)
            if not path.up_target:
                return to_meet
            return invert_rigid(self._up(path.up_target, stamp)) @ to_meet

    def fixed_frame(self, camera_frame: str) -> str:
        """The frame the camera's motion goes through by default.

        :data:`DEFAULT_FIXED_FRAME` when it is above the camera, else the root of its chain.
        """
        with self._lock:
            chain = self._ancestors(_frame(camera_frame))
        return DEFAULT_FIXED_FRAME if DEFAULT_FIXED_FRAME in chain else chain[-1]

    def _moving_edges(self, camera: str, fixed: str) -> list[_Edge]:
        """The dynamic edges between ``camera`` and ``fixed`` (both ways up to their meeting)."""
        path = self._path(fixed, camera)
        return [
            self._edges[child]
            for child in (*path.up_source, *path.up_target)
            if child in self._edges
        ]

    def camera_motion(
        self, camera_frame: str, t0_ns: int, t1_ns: int, fixed_frame: str | None = None
    ) -> np.ndarray:
        """The pose of ``camera_frame`` at ``t1_ns`` in its own frame at ``t0_ns`` (4×4).

        It maps points given in the camera frame at ``t1`` into the camera frame at ``t0``
        (tf2's ``lookupTransform(camera, t0, camera, t1, fixed_frame)``): the convention of
        :func:`dispeval_ros.core.egomotion.camera_motion` (``pose_t0⁻¹ · pose_t1``), what
        ``egomotion_residual`` takes; driving 1 m forward is a translation ``(0, 0, 1)``.
        ``fixed_frame``: default :meth:`fixed_frame`. A chain with no ``/tf`` edge (nothing
        moves it) is refused rather than read as a static camera.
        """
        camera = _frame(camera_frame)
        with self._lock:
            if not self._edges:
                raise TransformDataError(
                    f"no /tf transform received: the motion of the camera frame '{camera}' "
                    "needs its chain to a fixed frame such as odom on /tf"
                )
            if camera not in self.frames:
                known = ", ".join(self.frames)
                raise TransformChainError(
                    f"the camera frame '{camera}' is in no /tf or /tf_static transform; "
                    f"frames known: {known}"
                )
            fixed = _frame(fixed_frame) if fixed_frame else self.fixed_frame(camera)
            if not any(self._moving_edges(camera, fixed)):
                edges = ", ".join(e.name for e in self._edges.values())
                raise TransformChainError(
                    f"the chain from '{fixed}' to the camera frame '{camera}' holds no /tf edge "
                    f"(only /tf_static), so nothing moves the camera; /tf edges: {edges}"
                )
            first = self.lookup(fixed, camera, t0_ns)
            second = self.lookup(fixed, camera, t1_ns)
        return invert_rigid(first) @ second

    def ready(self, stamp_ns: int, camera_frame: str | None = None) -> bool:
        """True when every dynamic edge used has a sample at or after ``stamp_ns``.

        The edges used: those between ``camera_frame`` and its fixed frame when given, else
        those of the chains looked up so far, else every ``/tf`` edge. False without any.
        """
        until = self.answers_until(camera_frame)
        return until is not None and until >= stamp_ns

    def answers_until(self, camera_frame: str | None = None) -> int | None:
        """The latest stamp every dynamic edge used (:meth:`ready`'s) has reached, or None."""
        with self._lock:
            edges: list[_Edge]
            try:
                if camera_frame is not None:
                    camera = _frame(camera_frame)
                    edges = self._moving_edges(camera, self.fixed_frame(camera))
                else:
                    used = {
                        child
                        for path in self._paths.values()
                        for child in (*path.up_source, *path.up_target)
                        if child in self._edges
                    }
                    edges = [self._edges[c] for c in sorted(used)] or list(self._edges.values())
            except (TransformDataError, TransformChainError):
                return None
            if not edges or not all(e.stamps for e in edges):
                return None
            return min(e.stamps[-1] for e in edges)


def _raise_first(problems: list[str]) -> None:
    if problems:
        more = f" ({len(problems) - 1} more refused)" if len(problems) > 1 else ""
        raise TransformDataError(problems[0] + more)
