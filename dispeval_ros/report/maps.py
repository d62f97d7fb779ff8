"""Error-map thumbnails for the report: a few frames read from the bags again and scored.

The results database keeps no error maps, so the chosen frames are joined and scored again by
:class:`~dispeval_ros.stream.core.EvaluationCore` with ``error_images=True``.

Dense ground truth is rendered by :func:`~dispeval_ros.stream.images.colour_error` (turbo,
0–:data:`ERROR_RANGE_PX` px, criterion borders white). A LiDAR ground truth scores a few
thousand scattered points: drawn that way, shrunk to a thumbnail, they are a black image with
grey specks. So each scored point is drawn enlarged (:data:`POINT_RADIUS`, the largest error
on top where points meet) over the dimmed left image, on a scale set by the points' own errors
(the :data:`SPARSE_QUANTILE` th percentile of the errors shown, rounded up to a round number),
not the dense maps' fixed one.
"""

from __future__ import annotations

import base64
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dispeval_ros.errors import DispevalError, InputError
from dispeval_ros.io.store import ResultsStore

if TYPE_CHECKING:
    from dispeval_ros.io.bags import BagSource
    from dispeval_ros.stream.core import CoreConfig

DEFAULT_THUMBNAILS = 4
THUMBNAIL_WIDTH = 320
ERROR_RANGE_PX = 4.0
"""Dense error maps: turbo colour map from 0 to this many pixels (as ``colour_error``)."""
SPARSE_QUANTILE = 95.0
"""Sparse (LiDAR) error maps: the scale's top is this percentile of the points' errors."""
SPARSE_FLOOR_PX = 0.5
"""The smallest top of a sparse scale (all points nearly exact: still a readable scale)."""
POINT_RADIUS = 1
"""Sparse error maps: each point is a square of ``2·r + 1`` thumbnail pixels."""
BACKGROUND_LEVEL = 0.35
"""Sparse error maps: the left image under the points, dimmed to this share of its grey."""
IMAGE_TYPE = "sensor_msgs/msg/Image"


def core_config_from_run(config: Mapping[str, Any]) -> CoreConfig:
    """The evaluation core's configuration from a run's stored configuration."""
    from dispeval_ros.stream.core import CoreConfig

    if not isinstance(config.get("methods"), Mapping) or not isinstance(
        config.get("gt_topic"), str
    ):
        raise InputError(
            "the results do not record the method and ground-truth topics, so the bag frames "
            "cannot be scored again for thumbnails (use results written by 'dispeval bag')"
        )
    return CoreConfig.from_record(config)


def _png_uri(rgb: np.ndarray, max_width: int) -> str:
    import cv2

    height, width = rgb.shape[:2]
    if width > max_width:
        size = (max_width, max(1, round(height * max_width / width)))
        rgb = cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)
    ok, encoded = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:  # pragma: no cover - OpenCV always encodes RGB8
        raise InputError("cannot encode a thumbnail as PNG")
    return "data:image/png;base64," + base64.b64encode(encoded.tobytes()).decode("ascii")


def _turbo() -> np.ndarray:
    """The turbo colour map as 256 RGB rows (OpenCV's, as ``colour_error`` uses)."""
    import cv2

    ramp = np.arange(256, dtype=np.uint8).reshape(1, 256)
    return np.asarray(cv2.cvtColor(cv2.applyColorMap(ramp, cv2.COLORMAP_TURBO), cv2.COLOR_BGR2RGB))[
        0
    ]


def _legend_uri() -> str:
    return _png_uri(np.tile(_turbo()[None], (14, 1, 1)), 256)


# -- sparse (LiDAR) error maps ---------------------------------------------------------------


@dataclass(frozen=True)
class SparseMap:
    """The scored points of one error map: where they are and their errors (NaN left out)."""

    shape: tuple[int, int]
    rows: np.ndarray
    cols: np.ndarray
    errors: np.ndarray

    @classmethod
    def of(cls, error: np.ndarray) -> SparseMap:
        """The finite pixels of a full-size error map (NaN: not evaluated)."""
        rows, cols = np.nonzero(np.isfinite(error))
        height, width = error.shape[:2]
        return cls((int(height), int(width)), rows, cols, error[rows, cols].astype(np.float64))


def nice_ceiling(value: float) -> float:
    """The smallest of 1, 2, 2.5, 5 × 10^k that is ≥ ``value`` (``value`` > 0)."""
    power = 10.0 ** math.floor(math.log10(value))
    for step in (1.0, 2.0, 2.5, 5.0, 10.0):
        if step * power >= value * (1 - 1e-12):
            return step * power
    return 10.0 * power  # pragma: no cover - the loop ends at 10


def sparse_scale(maps: Iterable[SparseMap]) -> tuple[float, int]:
    """The top of the colour scale of sparse maps, and how many points set it.

    The :data:`SPARSE_QUANTILE` th percentile of every shown point's error, rounded up by
    :func:`nice_ceiling` (at least :data:`SPARSE_FLOOR_PX`); :data:`ERROR_RANGE_PX` without
    points.
    """
    values = [m.errors for m in maps if m.errors.size]
    if not values:
        return ERROR_RANGE_PX, 0
    errors = np.concatenate(values)
    top = float(np.percentile(errors, SPARSE_QUANTILE))
    return nice_ceiling(max(top, SPARSE_FLOOR_PX)), int(errors.size)


def colour_points(
    points: SparseMap,
    max_error: float,
    background: np.ndarray | None = None,
    max_width: int = THUMBNAIL_WIDTH,
) -> np.ndarray:
    """RGB8 thumbnail (at most ``max_width`` wide) of a sparse error map.

    Each point is a ``(2·POINT_RADIUS + 1)``-pixel square in turbo (0 → ``max_error`` px,
    clipped above), drawn at the thumbnail's scale so that it stays visible; where squares
    meet the largest error shows. Under them the grey ``background`` (the left image, same
    size as the map) at :data:`BACKGROUND_LEVEL`, else black.
    """
    import cv2

    height, width = points.shape
    scale = min(1.0, max_width / width)
    size = (max(1, round(width * scale)), max(1, round(height * scale)))
    if background is not None and background.shape[:2] == points.shape:
        grey = cv2.resize(background, size, interpolation=cv2.INTER_AREA)
        grey = (grey.astype(np.float64) * BACKGROUND_LEVEL).astype(np.uint8)
    else:
        grey = np.zeros((size[1], size[0]), np.uint8)
    rgb = np.repeat(grey[:, :, None], 3, axis=2)
    top = np.full((size[1], size[0]), -np.inf)
    rows = np.minimum(((points.rows + 0.5) * scale).astype(np.intp), size[1] - 1)
    cols = np.minimum(((points.cols + 0.5) * scale).astype(np.intp), size[0] - 1)
    for dy in range(-POINT_RADIUS, POINT_RADIUS + 1):
        for dx in range(-POINT_RADIUS, POINT_RADIUS + 1):
            y, x = rows + dy, cols + dx
            inside = (y >= 0) & (y < size[1]) & (x >= 0) & (x < size[0])
            np.maximum.at(top, (y[inside], x[inside]), points.errors[inside])
    covered = np.isfinite(top)
    codes = np.clip(top[covered] * (255.0 / max_error), 0.0, 255.0).astype(np.uint8)
    rgb[covered] = _turbo()[codes]
    return rgb


def left_image_topic(config: CoreConfig, topics: Mapping[str, Any]) -> str | None:
    """The left rectified image under a sparse map: the run's own, else the camera's.

    The run's left image topic when it read one; else the one ``sensor_msgs/Image`` topic
    beside the left CameraInfo (same namespace: ``/stereo/left/image_rect`` beside
    ``/stereo/left/camera_info``), a ``rect`` one preferred. None when there is no such topic
    or no single choice (the points are then drawn on black).
    """
    if config.left_image_topic:
        return config.left_image_topic
    if not config.left_info_topic or "/" not in config.left_info_topic:
        return None
    namespace = config.left_info_topic.rsplit("/", 1)[0] + "/"
    used = set(config.topics)
    images = [
        name
        for name, info in topics.items()
        if getattr(info, "msgtype", "") == IMAGE_TYPE
        and name.startswith(namespace)
        and name not in used
    ]
    rectified = [name for name in images if "rect" in name.rsplit("/", 1)[1]]
    for choice in (rectified, images):
        if len(choice) == 1:
            return choice[0]
    return None


def left_image_at(
    source: BagSource, topic: str, stamp: int, start_ns: int, stop_ns: int, tolerance_ns: int
) -> np.ndarray | None:
    """The 8-bit grey left image stamped nearest ``stamp`` (within ``tolerance_ns``), or None."""
    from dispeval_ros.io.grey import grey_from_frame
    from dispeval_ros.io.messages import image_from_msg

    best: tuple[int, Any] | None = None
    try:
        for _, _, msg in source.messages([topic], start_ns, stop_ns):
            frame = image_from_msg(msg, topic)
            gap = abs(frame.stamp - stamp)
            if gap <= tolerance_ns and (best is None or gap < best[0]):
                best = (gap, frame)
        return None if best is None else grey_from_frame(best[1], topic)
    except DispevalError:  # an image that cannot be shown: the points on black
        return None


def _note(sparse: bool, points: int, background: str | None) -> str:
    """What the legend of the maps says besides its ends (written once, shown by the page)."""
    if not sparse:
        return "black: not evaluated; white lines: criterion borders"
    under = f"over the dimmed left image {background}" if background else "on black"
    return (
        f"each scored LiDAR point drawn enlarged {under} (where points meet, the largest error "
        f"shows); scale: the {SPARSE_QUANTILE:g}th percentile of the errors of the {points} "
        "points shown, rounded up; no criterion borders"
    )


# -- choosing, scoring and rendering the frames ----------------------------------------------


def _spread(stamps: Sequence[int], count: int) -> list[int]:
    if count <= 0 or not stamps:
        return []
    if count >= len(stamps):
        return list(stamps)
    picks = np.linspace(0, len(stamps) - 1, count).round().astype(int)
    return [stamps[i] for i in sorted(set(picks.tolist()))]


def _match_bags(store: ResultsStore, bags: Sequence[Path]) -> dict[str, Path]:
    from dispeval_ros.offline.bag_eval import sequence_names

    sequences = store.sequences()
    sources = {}
    for sequence in sequences:
        source, _ = store.sequence_info(sequence)
        if source:
            sources[Path(source).resolve()] = sequence
    matched: dict[str, Path] = {}
    for bag, name in zip(bags, sequence_names(list(bags)), strict=True):
        found = sources.get(Path(bag).resolve()) or (name if name in sequences else None)
        if found is None:
            raise InputError(
                f"{bag}: matches no sequence of the results (sequences: {', '.join(sequences)})"
            )
        matched[found] = Path(bag)
    return matched


def _chosen_frames(
    store: ResultsStore, matched: Mapping[str, Path], count: int
) -> dict[str, list[int]]:
    """Sequence → the stamps shown: ``count`` frames shared out, evenly spaced in each."""
    order = [s for s in store.sequences() if s in matched]
    shares = [count // len(order) + (i < count % len(order)) for i in range(len(order))]
    chosen = {s: _spread(store.common_stamps(s), n) for s, n in zip(order, shares, strict=True)}
    return {sequence: stamps for sequence, stamps in chosen.items() if stamps}


def frames_to_show(store: ResultsStore, bags: Sequence[Path], count: int) -> int:
    """How many frames :func:`error_thumbnails` will look for (for a progress line)."""
    if count <= 0 or not bags:
        return 0
    return sum(map(len, _chosen_frames(store, _match_bags(store, bags), count).values()))


def error_thumbnails(
    store: ResultsStore,
    bags: Sequence[Path],
    count: int = DEFAULT_THUMBNAILS,
    config: CoreConfig | None = None,
    max_width: int = THUMBNAIL_WIDTH,
    progress: Any = None,
) -> dict[str, Any] | None:
    """Error-map thumbnails of ``count`` frames spread over the sequences of ``bags``.

    The chosen frames (evenly spaced over each sequence's common frames) are read from the bag
    again, joined, scored and rendered (dense or sparse: see the module docstring). A frame is
    looked for around its log time: its stamp moved by the sequence's ``stamp_offset_ns``
    (recorded by :func:`~dispeval_ros.offline.units.plan_bag`), within twice the join's
    margin (a frame whose offset drifted further is not shown). ``progress(done)`` is called
    after each frame looked for.
    """
    from dispeval_ros.io.bags import BagSource
    from dispeval_ros.offline.units import push_static_transforms
    from dispeval_ros.stream.core import EvaluationCore
    from dispeval_ros.stream.images import colour_error

    if count <= 0 or not bags:
        return None
    matched = _match_bags(store, bags)
    config = config or core_config_from_run(store.config())
    sparse = config.pointcloud
    margin = config.tolerance_ns + config.lateness_ns
    frames: list[dict[str, Any]] = []
    pending: list[tuple[dict[str, Any], list[tuple[str, SparseMap]], np.ndarray | None]] = []
    backgrounds: set[str] = set()
    done = 0
    for sequence, wanted in _chosen_frames(store, matched, count).items():
        all_stamps = store.stamps(sequence)
        offset = store.sequence_info(sequence)[1].get("stamp_offset_ns", 0)
        offset = offset if isinstance(offset, int) else 0
        with BagSource(matched[sequence]) as source:
            left = left_image_topic(config, source.topics) if sparse else None
            for stamp in wanted:
                core = EvaluationCore(config, error_images=True)
                push_static_transforms(source, core)
                found = None
                logged = stamp + offset
                window = (logged - 2 * margin, logged + 2 * margin + 1)
                for topic, log_ns, msg in source.messages(list(config.topics), *window):
                    for frame_set in core.push(topic, msg, log_ns):
                        if frame_set.stamp == stamp and found is None:
                            found = core.score(frame_set)
                for frame_set in core.flush():
                    if frame_set.stamp == stamp and found is None:
                        found = core.score(frame_set)
                done += 1
                if progress is not None:
                    progress(done)
                if found is None or found.partition is None:
                    continue
                entry: dict[str, Any] = {
                    "sequence": sequence,
                    "stamp": str(stamp),
                    "first_stamp": str(all_stamps[0]),
                    "index": all_stamps.index(stamp),
                }
                frames.append(entry)
                if sparse:
                    image = None
                    if left is not None:
                        image = left_image_at(source, left, stamp, *window, config.tolerance_ns)
                        if image is not None:
                            backgrounds.add(left)
                    maps = [(m, SparseMap.of(error)) for m, error in found.errors.items()]
                    pending.append((entry, maps, image))
                    continue
                partition = found.partition
                entry["images"] = [
                    [method, _png_uri(colour_error(error, partition, ERROR_RANGE_PX), max_width)]
                    for method, error in found.errors.items()
                ]
    if not frames:
        return None
    top, points = sparse_scale(m for _, maps, _ in pending for _, m in maps)
    for entry, maps, image in pending:
        entry["images"] = [
            [method, _png_uri(colour_points(m, top, image, max_width), max_width)]
            for method, m in maps
        ]
    background = ", ".join(sorted(backgrounds)) or None
    return {
        "max_error": top if sparse else ERROR_RANGE_PX,
        "sparse": sparse,
        "note": _note(sparse, points, background),
        "legend": _legend_uri(),
        "frames": frames,
    }
