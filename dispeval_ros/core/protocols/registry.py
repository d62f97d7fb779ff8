"""The protocols by name and what works across them: dispatch, digit checks, objectives.

Dispatch goes through the :class:`Protocol` object's own functions, so a protocol is added
in one module and here; an unknown name is an error, never a silent default.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from dispeval_ros.core.protocols.common import (
    EXACT,
    OFFICIAL,
    Arithmetic,
    FrameData,
    FrameResult,
    Protocol,
)
from dispeval_ros.core.protocols.eth3d import ETH3D
from dispeval_ros.core.protocols.kitti2012 import KITTI2012
from dispeval_ros.core.protocols.kitti2015 import KITTI2015
from dispeval_ros.core.protocols.middeval3 import MIDDEVAL3
from dispeval_ros.errors import ConfigurationError

PROTOCOLS: dict[str, Protocol] = {p.name: p for p in (MIDDEVAL3, KITTI2015, KITTI2012, ETH3D)}


def get_protocol(name: str) -> Protocol:
    """The protocol called ``name`` or a one-line error listing the known ones."""
    try:
        return PROTOCOLS[name]
    except KeyError:
        raise ConfigurationError(
            f"unknown protocol '{name}'; choose from {', '.join(PROTOCOLS)}"
        ) from None


def resolve(protocol: Protocol | str) -> Protocol:
    """A protocol given by name or as the preset itself (callers take either)."""
    return get_protocol(protocol) if isinstance(protocol, str) else protocol


def evaluate_frame(
    protocol: Protocol | str,
    data: FrameData,
    estimate: np.ndarray,
    arithmetic: Arithmetic | None = None,
) -> FrameResult:
    """One estimate on one frame under ``protocol``.

    By default the official arithmetic, with the exact twin in ``result.exact``; with an
    ``arithmetic``, only that one.
    """
    chosen = resolve(protocol)
    if arithmetic is None:
        result = evaluate_frame(chosen, data, estimate, OFFICIAL)
        result.exact = evaluate_frame(chosen, data, estimate, EXACT)
        return result
    return chosen.frame_function(data, estimate, arithmetic)


def summarize_frames(
    protocol: Protocol | str,
    frames: Sequence[FrameResult],
    arithmetic: Arithmetic = OFFICIAL,
) -> dict[str, dict[str, float]]:
    """The benchmark's summary over ``frames`` (its own way of combining them)."""
    chosen = resolve(protocol)
    if not frames:
        raise ConfigurationError("no frame to summarise")
    return chosen.summary_function(frames, arithmetic)


def moved_digits(
    protocol: Protocol,
    official: Mapping[str, Mapping[str, float]],
    exact: Mapping[str, Mapping[str, float]],
) -> list[tuple[str, str, float, float]]:
    """``(region, column, official, exact)`` where the printed two decimals differ."""
    moved = []
    for region, values in official.items():
        for column in protocol.columns:
            have, want = values.get(column, math.nan), exact.get(region, {}).get(column, math.nan)
            if f"{have:.2f}" != f"{want:.2f}":
                moved.append((region, column, have, want))
    return moved


def objective_matrix(
    protocol: Protocol | str, results: Mapping[str, Sequence[FrameResult]]
) -> tuple[list[str], list[str], np.ndarray]:
    """Methods, objective names (``frame/region/column``) and values, for the A* Groups.

    The objectives are the protocol's lower-is-better columns in every region of every
    frame that all methods were scored on (a missing value counts as worst).
    """
    chosen = resolve(protocol)
    methods = list(results)
    names: list[str] = []
    columns: list[list[float]] = []
    by_frame = {m: {f.frame: f for f in results[m]} for m in methods}
    frames = list(dict.fromkeys(f.frame for m in methods for f in results[m]))
    for frame in frames:
        for region in chosen.regions:
            for column in chosen.objectives:
                values = []
                for method in methods:
                    found = by_frame[method].get(frame)
                    values.append(
                        found.values.get(region, {}).get(column, math.nan) if found else math.nan
                    )
                if all(math.isnan(v) for v in values):
                    continue
                names.append(f"{frame}/{region}/{column}")
                columns.append(values)
    matrix = np.array(columns, dtype=np.float64).T if columns else np.zeros((len(methods), 0))
    return methods, names, matrix
