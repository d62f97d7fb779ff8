"""``dispeval merge``: one results database from several made separately (per machine, night…).

Runs merge when they were made with the same configuration (the bags aside): their units are
copied in the order given, so merging the results of two halves of a list of bags gives the
database of one run over the whole list, and summaries and reports cover every sequence.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from dispeval_ros.core.provenance import provenance_record
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.store import ResultsStore

PER_RUN_KEYS = ("bags",)
"""Configuration keys that differ between the runs being merged (concatenated in the result)."""


@dataclass(frozen=True)
class MergeReport:
    """What a merge wrote: results folder, runs, sequences and units."""

    path: Path
    runs: int
    sequences: int
    units: int


def merged_config(configs: Sequence[tuple[Path, dict[str, object]]]) -> dict[str, object]:
    """The configuration of the merged results; refuses (one line) runs configured differently."""
    (first_path, first), *others = configs
    shared = {key: value for key, value in first.items() if key not in PER_RUN_KEYS}
    for path, config in others:
        theirs = {key: value for key, value in config.items() if key not in PER_RUN_KEYS}
        for key in [*shared, *(key for key in theirs if key not in shared)]:
            if shared.get(key) != theirs.get(key):
                raise ConfigurationError(
                    f"cannot merge {path}: '{key}' is {_show(theirs.get(key))} there but "
                    f"{_show(shared.get(key))} in {first_path}; only runs with the same "
                    "configuration merge"
                )
    merged = dict(first)
    for key in PER_RUN_KEYS:
        if any(key in config for _, config in configs):
            merged[key] = [item for _, config in configs for item in _items(config.get(key))]
    return merged


def merge_results(out: Path, sources: Sequence[Path]) -> MergeReport:
    """Write ``out/results.sqlite`` holding every unit of ``sources``, in the order given."""
    if not sources:
        raise ConfigurationError("nothing to merge: give at least one results folder")
    stores = []
    try:
        for source in sources:
            stores.append(ResultsStore.open(source))
        config = merged_config([(store.path, store.config()) for store in stores])
        units = 0
        with ResultsStore.create(out, config) as merged:
            for store in stores:
                units += merged.add_results(store)
            merged.set_provenance(
                provenance_record(
                    config,
                    {
                        "merged": [
                            {"results": str(store.path), "provenance": store.provenance()}
                            for store in stores
                        ]
                    },
                )
            )
            sequences = len(merged.sequences())
            path = merged.path
    finally:
        for store in stores:
            store.close()
    return MergeReport(path, len(stores), sequences, units)


def _items(value: object) -> list[object]:
    if value is None:
        return []
    return list(value) if isinstance(value, (list, tuple)) else [value]


def _show(value: object) -> str:
    text = "(absent)" if value is None else repr(value)
    return text if len(text) <= 80 else text[:79] + "…"
