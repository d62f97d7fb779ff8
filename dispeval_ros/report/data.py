"""Read a results database into the compact, JSON-able structure the HTML report embeds.

The browser must recompute every objective exactly as Python does, so the report carries the
float64 accumulator rows (``sums``) of every (sequence, frame, method, criterion), not rounded
measure values: sequence totals are then sums of sums in frame order (bit-identical to
:meth:`ResultsStore.sequence_scores`) and every measure is derived from them by a small
*recipe* (numerator field, denominator field, scale) that mirrors
:func:`dispeval_ros.core.measures.measure_from_sums`.

Size: the rows form a dense ``(frame, criterion, method)`` grid. Each accumulator field is one
column: all-zero columns (unused bad-x thresholds) are dropped, integral columns (counts) are
stored as the smallest unsigned integer type that holds them, the others as float64. Columns
are byte-shuffled (all first bytes, then all second bytes, …: exponents and high bytes
compress well), deflated with zlib and base64-encoded; the browser inflates them with
``DecompressionStream``. A 100-method × 1000-frame × 3-criterion database gives about 18 MB.

It also holds the Python reference of the in-browser models: :func:`selection_objectives`
builds the method × objective matrix of a :class:`Selection` from the database alone (through
``ResultsStore`` queries), the way ``dispeval_ros.summary`` does, and
:func:`evaluate_selection` runs :func:`dispeval_ros.core.models.evaluate_models` on it.
"""

from __future__ import annotations

import base64
import math
import zlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any, cast

import numpy as np

from dispeval_ros.core.measures import HIGHER_IS_BETTER, SUM_FIELDS, applies, quantile_level
from dispeval_ros.core.models import ModelResult, evaluate_models
from dispeval_ros.core.objectives import default_objective_measures, has_points
from dispeval_ros.errors import ConfigurationError, InputError
from dispeval_ros.io.jsonio import json_safe
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.report.latency import latency_data
from dispeval_ros.report.maps import (  # the thumbnails: also from here, their old home
    DEFAULT_THUMBNAILS,  # noqa: F401
    ERROR_RANGE_PX,  # noqa: F401
    THUMBNAIL_WIDTH,  # noqa: F401
    core_config_from_run,  # noqa: F401
    error_thumbnails,  # noqa: F401
)
from dispeval_ros.report.recipes import (  # recipe_values: also from here, its old home
    measure_recipe,
    recipe_values,  # noqa: F401
)
from dispeval_ros.report.reference import reference_text
from dispeval_ros.report.sweep import sweep_data
from dispeval_ros.report.temporal import temporal_data
from dispeval_ros.summary import GRANULARITIES

FORMAT_VERSION = 1
MAX_PROBLEMS = 2000
"""Problems listed in the report (the total is always given)."""

_UINT_TYPES = (("u8", np.uint8, 2**8), ("u16", np.uint16, 2**16), ("u32", np.uint32, 2**32))
_ITEMSIZE = {"u8": 1, "u16": 2, "u32": 4, "f64": 8, "zero": 0}
_DTYPES: dict[str, np.dtype[Any]] = {
    "u8": np.dtype("<u1"),
    "u16": np.dtype("<u2"),
    "u32": np.dtype("<u4"),
    "f64": np.dtype("<f8"),
}

# -- selections and the Python reference of the in-browser models --------------------------


@dataclass(frozen=True)
class Selection:
    """What the user picked: sequences (and frames), criteria, measures, methods, granularity.

    Lists are filtered in database order whatever their order here. ``frames`` maps a
    sequence to 0-based indices into :meth:`ResultsStore.stamps` (absent: every frame).
    """

    sequences: tuple[str, ...]
    criteria: tuple[str, ...]
    measures: tuple[str, ...]
    methods: tuple[str, ...]
    granularity: str = "sequence"
    frames: Mapping[str, Sequence[int]] | None = None

    def to_dict(self) -> dict[str, Any]:
        """The JSON form the browser's ``dispevalModels(selection)`` takes."""
        return {
            "sequences": list(self.sequences),
            "criteria": list(self.criteria),
            "measures": list(self.measures),
            "methods": list(self.methods),
            "granularity": self.granularity,
            "frames": None
            if self.frames is None
            else {name: [int(i) for i in indices] for name, indices in self.frames.items()},
        }


def default_selection(store: ResultsStore, overlapping: Iterable[str] | None = None) -> Selection:
    """What the summary compares, as the report opens.

    Every sequence, frame and method, the partition criteria (overlapping legacy criteria
    left out), the default objectives of the measures stored per sequence (``sze`` and
    ``bmpre`` where stored; ``gtfree:`` criteria left out then; without ground truth vpe on
    them).
    """
    chosen = default_objective_measures(store.measures())
    skip = set(store.overlapping_criteria() if overlapping is None else overlapping)
    return Selection(
        sequences=tuple(store.sequences()),
        criteria=tuple(  # ground-truth-free criteria only where their measures are compared
            c for c in store.criteria() if c not in skip and any(applies(m, c) for m in chosen)
        ),
        measures=tuple(chosen),
        methods=tuple(store.methods()),
    )


def _chosen_stamps(
    store: ResultsStore, sequence: str, frames: Mapping[str, Sequence[int]] | None
) -> list[int]:
    stamps = store.stamps(sequence)
    if frames is None or sequence not in frames:
        return stamps
    indices = sorted({int(i) for i in frames[sequence] if 0 <= int(i) < len(stamps)})
    return [stamps[i] for i in indices]


def common_stamps(
    store: ResultsStore,
    sequence: str,
    methods: Sequence[str],
    frames: Mapping[str, Sequence[int]] | None = None,
) -> list[int]:
    """The chosen stamps where every chosen method present in the sequence has a row.

    With every method chosen this is :meth:`ResultsStore.common_stamps` (the frames every
    method stored for the sequence delivered). Methods with no frame at all in the sequence
    do not empty it: their objectives there are NaN (worst).
    """
    chosen = _chosen_stamps(store, sequence, frames)
    if set(methods) == set(store.methods()):
        allowed = set(chosen)
        return [s for s in store.common_stamps(sequence) if s in allowed]
    delivered = []
    for method in methods:
        stamps = {cast(int, row["stamp"]) for row in store.frame_rows(sequence, method)}
        if stamps:
            delivered.append(stamps)
    if not delivered:
        return []
    return [s for s in chosen if all(s in stamps for stamps in delivered)]


def _ordered(chosen: Iterable[str], order: Sequence[str]) -> list[str]:
    wanted = set(chosen)
    return [name for name in order if name in wanted]


def _value(scores: Mapping[str, Any], method: str, criterion: str, measure: str) -> float:
    if method not in scores or criterion not in scores[method]:
        return math.nan
    value = float(scores[method][criterion][measure])
    return -value if measure in HIGHER_IS_BETTER else value


def selection_objectives(
    store: ResultsStore, selection: Selection
) -> tuple[list[str], list[str], np.ndarray]:
    """Methods, objective names and the methods × objectives matrix of a selection.

    Per selected sequence (database order), on its common stamps: per (criterion, measure)
    the measure of the summed sums (``granularity='sequence'``), or per frame, per
    (criterion, measure) the frame's measure (``'frame'``). A criterion no chosen method has
    there (no such points) gives no objective, as in the summary, nor does a measure on a
    criterion it does not apply to (:func:`skipped_pairs`); a method missing a
    criterion others have is NaN there. Higher-is-better measures (density) are negated. Names as the summary:
    ``criterion/measure @sequence`` and ``criterion/measure @sequence:stamp``.
    """
    if selection.granularity not in GRANULARITIES:
        raise ConfigurationError(
            f"granularity must be one of {', '.join(GRANULARITIES)}, got '{selection.granularity}'"
        )
    methods = _ordered(selection.methods, store.methods())
    criteria = _ordered(selection.criteria, store.criteria())
    measures = _ordered(selection.measures, store.measures())
    names: list[str] = []
    columns: list[list[float]] = []
    for sequence in _ordered(selection.sequences, store.sequences()):
        stamps = common_stamps(store, sequence, methods, selection.frames)
        if not stamps or not methods:
            continue
        if selection.granularity == "sequence":
            parts = [(f" @{sequence}", store.sequence_scores(sequence, stamps=stamps))]
        else:
            parts = [
                (f" @{sequence}:{stamp}", store.frame_scores(sequence, stamp)) for stamp in stamps
            ]
        for label, scores in parts:
            for criterion in criteria:
                if not has_points({m: scores[m] for m in methods if m in scores}, criterion):
                    continue  # no such points there (e.g. no boundary in KITTI's GT): no objective
                for measure in measures:
                    if not applies(measure, criterion):
                        continue  # GT measures on gtfree: criteria, vpe on GT ones: undefined
                    names.append(f"{criterion}/{measure}{label}")
                    columns.append([_value(scores, m, criterion, measure) for m in methods])
    matrix = np.array(columns, dtype=np.float64).T if columns else np.empty((len(methods), 0))
    return methods, names, matrix.reshape(len(methods), len(names))


def skipped_pairs(selection: Selection) -> list[str]:
    """The chosen ``criterion/measure`` pairs that give no objective: the measure is undefined there.

    GT measures on ``gtfree:`` criteria, ``vpe``/``lrc`` on GT criteria (as the page says).
    """
    return [f"{c}/{m}" for c in selection.criteria for m in selection.measures if not applies(m, c)]


def evaluate_selection(
    store: ResultsStore, selection: Selection
) -> tuple[list[str], list[str], np.ndarray, ModelResult | None]:
    """:func:`selection_objectives` and the models on it (None without methods or objectives)."""
    methods, names, matrix = selection_objectives(store, selection)
    if not methods or not names:
        return methods, names, matrix, None
    return methods, names, matrix, evaluate_models(methods, matrix)


# -- the compact arrays ----------------------------------------------------------------------


def _column_type(values: np.ndarray) -> str:
    if not np.any(values) and not np.any(np.isnan(values)):
        return "zero"
    if np.all(np.isfinite(values)) and np.all(values >= 0) and np.all(values == np.floor(values)):
        top = float(values.max())
        for name, _, limit in _UINT_TYPES:
            if top < limit:
                return name
    return "f64"


def _shuffled(values: np.ndarray, kind: str) -> bytes:
    """The column's little-endian bytes, byte-plane by byte-plane (all first bytes first)."""
    raw = np.ascontiguousarray(values.astype(_DTYPES[kind]))
    size = _ITEMSIZE[kind]
    if size == 1:
        return raw.tobytes()
    return np.ascontiguousarray(raw.view(np.uint8).reshape(-1, size).T).tobytes()


def _unshuffled(buffer: bytes, offset: int, rows: int, kind: str) -> np.ndarray:
    size = _ITEMSIZE[kind]
    planes = np.frombuffer(buffer, np.uint8, rows * size, offset).reshape(size, rows)
    return np.ascontiguousarray(planes.T).view(_DTYPES[kind]).reshape(rows).astype(np.float64)


def encode_columns(columns: Sequence[tuple[str, np.ndarray]], level: int = 6) -> dict[str, Any]:
    """Encode named 1-D columns of equal length: types, zlib of the shuffled bytes, base64."""
    rows = int(columns[0][1].size) if columns else 0
    described, chunks = [], []
    for name, column in columns:
        values = np.asarray(column, dtype=np.float64).ravel()
        kind = _column_type(values)
        described.append({"name": name, "type": kind})
        if kind != "zero":
            chunks.append(_shuffled(values, kind))
    payload = zlib.compress(b"".join(chunks), level)
    return {
        "rows": rows,
        "encoding": "zlib+base64",
        "columns": described,
        "payload": base64.b64encode(payload).decode("ascii"),
    }


def decode_columns(encoded: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """Inverse of :func:`encode_columns` (float64 columns), as the browser decodes them."""
    rows = int(encoded["rows"])
    buffer = zlib.decompress(base64.b64decode(encoded["payload"]))
    offset = 0
    result: dict[str, np.ndarray] = {}
    for column in encoded["columns"]:
        kind = column["type"]
        if kind == "zero":
            result[column["name"]] = np.zeros(rows)
            continue
        result[column["name"]] = _unshuffled(buffer, offset, rows, kind)
        offset += rows * _ITEMSIZE[kind]
    if offset != len(buffer):
        raise InputError("report payload has trailing bytes; it is damaged")
    return result


def decode_arrays(data: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """The report's grid as arrays, decoded as the browser decodes it.

    ``sums`` (frames, criteria, methods, fields), ``present`` (frames, criteria, methods) and
    ``stored:NAME`` (frames, criteria, methods) per stored quantile measure.
    """
    arrays = data["arrays"]
    shape = (arrays["frames"], arrays["criteria"], arrays["methods"])
    columns = decode_columns(arrays)
    fields = data["fields"]
    sums = np.stack([columns[f"sum:{name}"] for name in fields], axis=-1)
    result = {
        "sums": sums.reshape((*shape, len(fields))),
        "present": columns["present"].reshape(shape).astype(bool),
    }
    for name in arrays.get("stored", []):
        result[f"stored:{name}"] = columns[f"stored:{name}"].reshape(shape)
    return result


# -- the report data -------------------------------------------------------------------------


def _grid(
    store: ResultsStore, sequences: list[str], methods: list[str], criteria: list[str]
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], dict[str, Any]]:
    """Every stored row in a dense (frame, criterion, method) grid, plus what the rows say."""
    stamps = {s: store.stamps(s) for s in sequences}
    frames = sum(len(v) for v in stamps.values())
    shape = (frames, len(criteria), len(methods))
    sums = np.zeros((*shape, len(SUM_FIELDS)), dtype=np.float64)
    present = np.zeros(shape, dtype=np.uint8)
    stored_names = [m for m in store.measures() if quantile_level(m) is not None]
    stored = {name: np.full(shape, np.nan) for name in stored_names}
    method_at = {m: i for i, m in enumerate(methods)}
    criterion_at = {c: i for i, c in enumerate(criteria)}
    relative = dict.fromkeys(methods, False)
    thresholds: np.ndarray | None = None
    policy = ""
    frame = 0
    for sequence in sequences:
        for stamp in stamps[sequence]:
            for method, scores in store.frame_scores(sequence, stamp).items():
                m = method_at[method]
                relative[method] = relative[method] or bool(scores.relative)
                thresholds, policy = scores.thresholds, scores.policy
                for row, criterion in enumerate(scores.criteria):
                    c = criterion_at[criterion]
                    sums[frame, c, m] = scores.sums[row]
                    present[frame, c, m] = 1
                    for name in stored_names:
                        value = scores.quantiles.get(criterion, {}).get(name, math.nan)
                        stored[name][frame, c, m] = value
            frame += 1
    info = {
        "overlapping": store.overlapping_criteria(),
        "relative": [relative[m] for m in methods],
        "thresholds": thresholds,
        "policy": policy,
    }
    return sums, present, stored, info


def build_report_data(
    store: ResultsStore,
    *,
    title: str | None = None,
    thumbnails: Mapping[str, Any] | None = None,
    level: int = 6,
    objective_measures: Sequence[str] | None = None,
    granularity: str = "sequence",
) -> dict[str, Any]:
    """The JSON-able report data of a results database (see the module docstring).

    ``objective_measures``, ``granularity``: the run's, for the latency view's A* Groups
    (:func:`~dispeval_ros.report.latency.latency_data`); None: the default rule.
    """
    sequences, methods, criteria = store.sequences(), store.methods(), store.criteria()
    measures = store.measures()
    if not methods or not measures:
        raise InputError(f"{store.path} holds no scored frame yet; nothing to report")
    sums, present, stored, info = _grid(store, sequences, methods, criteria)
    thresholds = info["thresholds"] if info["thresholds"] is not None else np.zeros(1)
    columns: list[tuple[str, np.ndarray]] = [("present", present.ravel())]
    columns += [(f"sum:{name}", sums[..., i].ravel()) for i, name in enumerate(SUM_FIELDS)]
    columns += [(f"stored:{name}", values.ravel()) for name, values in stored.items()]
    arrays = encode_columns(columns, level)
    arrays.update(
        frames=int(sums.shape[0]),
        criteria=len(criteria),
        methods=len(methods),
        layout="frame, criterion, method (method fastest)",
        stored=list(stored),
    )
    sequence_list = []
    for sequence in sequences:
        source, seq_info = store.sequence_info(sequence)
        stamps = store.stamps(sequence)
        first = stamps[0] if stamps else 0
        sequence_list.append(
            {
                "name": sequence,
                "source": source,
                "info": json_safe(seq_info),
                "stamps": [str(s) for s in stamps],
                "times": [(s - first) / 1e9 for s in stamps],
                "counts": [
                    [method, c.matched, c.unmatched, c.dropped, c.failed]
                    for method, c in store.match_counts(sequence).items()
                ],
            }
        )
    problems = store.problems()
    overlapping = info["overlapping"]
    defaults = default_selection(store, overlapping).to_dict()
    return {
        "format": FORMAT_VERSION,
        "title": title or f"dispeval report: {store.path.parent.name or store.path.name}",
        "created": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "source": str(store.path),
        "config": json_safe(store.config()),
        "reference": reference_text(store.config()),
        "policy": info["policy"],
        "thresholds": json_safe([float(t) for t in thresholds]),
        "fields": list(SUM_FIELDS),
        "sequences": sequence_list,
        "methods": methods,
        "relative": info["relative"],
        "criteria": [
            {
                "name": c,
                "overlapping": c in overlapping,
                "applies": [applies(m, c) for m in measures],
            }
            for c in criteria
        ],
        "measures": [measure_recipe(m, thresholds) for m in measures],
        "problems": {
            "total": len(problems),
            "shown": [
                [p.sequence, None if p.stamp is None else str(p.stamp), p.method, p.message]
                for p in problems[:MAX_PROBLEMS]
            ],
        },
        "arrays": arrays,
        "defaults": {**defaults, "model": "astar"},
        "thumbnails": json_safe(thumbnails) if thumbnails else None,
        "latency": latency_data(store, objective_measures, granularity),
        "temporal": temporal_data(store),
        "sweep": sweep_data(store, objective_measures, granularity),
    }
