"""The latency part of the report: timing measures, per-frame delays, the first A* group.

Per sequence and method the timing measures and the per-frame delays, and the A* Groups over
the run's objectives (which may include ``latency_p95``).

The values are those of ``summary.json`` (:func:`~dispeval_ros.summary.summarize` computes them
here too, with the run's objective measures), so the page plots the numbers the latency table
prints. None where no latency is recorded (a database written before arrival times were, results
of ``dispeval eval --out``): the page then says "latency not recorded".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from dispeval_ros.core.records import FrameTiming
from dispeval_ros.core.timing import TIMING_MEASURES
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.jsonio import json_safe
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.summary import SequenceSummary, summarize

NOT_RECORDED = (
    "latency not recorded (results written before dispeval recorded arrival times, or scored "
    "from files: no arrival to measure)"
)
"""What the report says instead of a latency plot: one wording for the page and the figures."""
DEFAULT_LATENCY_MEASURE = "latency_p95"
"""The latency measure on the x axis as the report opens."""


def latency_label(name: str) -> str:
    """A timing measure's axis label with its unit (:data:`TIMING_MEASURES`): ``latency_p95 [ms]``."""
    return f"{name} [{TIMING_MEASURES[name].unit}]"


DELAY_LABEL = "delay [ms]"
"""The per-frame delay axis: arrival − header stamp, in the unit of the latency measures."""


def latency_measures() -> list[dict[str, Any]]:
    """The timing measures as the page lists them: name, unit, direction, text, axis label."""
    return [
        {
            "name": m.name,
            "unit": m.unit,
            "higher": m.higher_is_better,
            "text": m.text,
            "label": latency_label(m.name),
        }
        for m in TIMING_MEASURES.values()
    ]


def _first_group(summary: SequenceSummary) -> list[str]:
    if summary.models is None:
        return []
    return [m for m, group in summary.models.groups.items() if group == 1]


def _sequence_latency(
    store: ResultsStore, summary: SequenceSummary, entries: dict[str, list[FrameTiming]]
) -> dict[str, Any] | None:
    """One sequence's latency: values per method, per-frame delays, the first A* group."""
    timing = summary.timing
    if not timing:  # no arrival recorded for the sequence
        return None
    frame_of = {stamp: i for i, stamp in enumerate(store.stamps(summary.sequence))}
    delays = {}
    for method, found in entries.items():
        ordered = sorted(found, key=lambda e: frame_of.get(e.stamp, math.inf))
        delays[method] = [
            [frame_of[e.stamp], e.delay / 1e6] for e in ordered if e.stamp in frame_of
        ]
    return {
        "methods": list(timing),
        "values": {
            method: {name: t.value(name) for name in TIMING_MEASURES}
            for method, t in timing.items()
        },
        "frames": {method: t.frames for method, t in timing.items()},
        "delays": delays,
        "objectives": summary.objectives,
        "groups": dict(summary.models.groups) if summary.models else None,
        "first_group": _first_group(summary),
    }


def latency_data(
    store: ResultsStore,
    objective_measures: Sequence[str] | None = None,
    granularity: str = "sequence",
) -> dict[str, Any]:
    """The report's latency block (``recorded`` false without latency: see the module docstring).

    ``objective_measures`` and ``granularity``: the run's (``summary.json``'s); None: the
    default rule. Where the models cannot be made on them (a timing objective undefined: too
    few arrivals), the groups are left out and ``problem`` says why.
    """
    base = {"measures": latency_measures(), "not_recorded": NOT_RECORDED}
    found = {s: store.timing(s) or {} for s in store.sequences()} if store.records_timing() else {}
    if not any(found.values()):  # an older database, or results scored from files
        return {**base, "recorded": False}
    problem = None
    try:
        summary = summarize(store, list(objective_measures or []), granularity)
    except ConfigurationError as error:
        problem = str(error)
        summary = summarize(store)  # the timing values do not depend on the objectives
    sequences = {
        s.sequence: _sequence_latency(store, s, found[s.sequence]) for s in summary.sequences
    }
    if problem:
        for block in sequences.values():
            if block:
                block.update(objectives=[], groups=None, first_group=[])
    return json_safe(
        {
            **base,
            "recorded": True,
            "default": DEFAULT_LATENCY_MEASURE,
            "delay_label": DELAY_LABEL,
            "objective_measures": list(objective_measures or []) if problem else summary.measures,
            "granularity": granularity,
            "problem": problem,
            "sequences": sequences,
        }
    )
