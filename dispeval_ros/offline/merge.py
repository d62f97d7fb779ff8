"""``dispeval merge``: one results database from several made separately (per machine, night…).

Runs merge when they were made with the same configuration (the bags aside): their units are
copied in the order given, so merging the results of two halves of a list of bags gives the
database of one run over the whole list, and summaries and reports cover every sequence.

Beside ``OUT/results.sqlite`` the merge writes the ``frames.csv`` and ``summary.json`` a
``dispeval bag`` run over all the bags writes
(:func:`~dispeval_ros.offline.records.write_run_files`), its provenance naming the merged
results and theirs.

The merge is written to a scratch folder beside ``OUT`` and its files are renamed into place
only once every input was read and the summary made: a refused merge (a unit twice, a damaged
input…) leaves ``OUT`` as it was, so the corrected command runs as it is (merge has no
``--resume``). ``results.sqlite`` is renamed last, so a folder holding it holds the other two.
"""

from __future__ import annotations

import os
import shutil
import sqlite3
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from dispeval_ros.core.provenance import provenance_record
from dispeval_ros.errors import ConfigurationError, InputError
from dispeval_ros.io.store import FRAMES_CSV, RESULTS_FILE, SUMMARY_JSON, TIMING_JSON, ResultsStore
from dispeval_ros.offline.records import RunFiles, write_run_files

PER_RUN_KEYS = ("bags",)
"""Configuration keys that differ between the runs being merged (concatenated in the result)."""


@dataclass(frozen=True)
class MergeReport:
    """What a merge wrote: results database, runs, sequences, units, and the CSV and summary."""

    path: Path
    runs: int
    sequences: int
    units: int
    files: RunFiles


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


def merge_results(
    out: Path,
    sources: Sequence[Path],
    measures: Sequence[str] | None = None,
    granularity: str = "sequence",
) -> MergeReport:
    """Write ``out/results.sqlite`` holding every unit of ``sources``, in the order given.

    And ``out/frames.csv`` and ``out/summary.json`` (``measures`` and ``granularity`` as in
    :func:`~dispeval_ros.summary.summarize`). Nothing is written to ``out`` unless the whole
    merge succeeds (see the module docstring).
    """
    if not sources:
        raise ConfigurationError("nothing to merge: give at least one results folder")
    out = Path(out)
    _check_target(out)
    stores = []
    try:
        for source in sources:
            stores.append(ResultsStore.open(source))
            stores[-1].verify()  # a damaged input is refused before anything is copied
        config = merged_config([(store.path, store.config()) for store in stores])
        scratch = Path(tempfile.mkdtemp(prefix=f".{out.name}.merging-", dir=_existing(out.parent)))
        try:
            units, sequences, files = _merge_into(
                scratch, out / RESULTS_FILE, config, stores, measures, granularity
            )
            out.mkdir(parents=True, exist_ok=True)
            _check_target(out)
            if (scratch / TIMING_JSON).exists():  # written where latency was recorded
                os.replace(scratch / TIMING_JSON, out / TIMING_JSON)
            for name in (FRAMES_CSV, SUMMARY_JSON, RESULTS_FILE):  # the database last
                os.replace(scratch / name, out / name)
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
    finally:
        for store in stores:
            store.close()
    return MergeReport(out / RESULTS_FILE, len(stores), sequences, units, files)


def _merge_into(
    folder: Path,
    target: Path,
    config: dict[str, object],
    stores: Sequence[ResultsStore],
    measures: Sequence[str] | None,
    granularity: str,
) -> tuple[int, int, RunFiles]:
    """Units, sequences and the run's files written to ``folder`` (``target``: its database)."""
    units = 0
    with ResultsStore.create(folder, config) as merged:
        merged.path = target  # refusals name the results as the user will find them
        for store in stores:
            try:
                units += merged.add_results(store)
            except sqlite3.DatabaseError as error:  # damage the opening checks did not reach
                raise InputError(
                    f"{store.path}: cannot read the results database ({error})"
                ) from None
        provenance = provenance_record(
            config,
            {
                "merged": [
                    {"results": str(store.path), "provenance": store.provenance()}
                    for store in stores
                ]
            },
        )
        merged.set_provenance(provenance)
        files = write_run_files(merged, folder, provenance, measures, granularity)
        return units, len(merged.sequences()), files


def _check_target(out: Path) -> None:
    """``out`` is a folder (or nothing yet) without results: a merge never overwrites one."""
    if out.exists() and not out.is_dir():
        raise InputError(f"{out} is a file; merge writes a results folder")
    if (out / RESULTS_FILE).exists():
        raise ConfigurationError(
            f"{out} already holds results ({RESULTS_FILE}); merge into a new folder"
        )


def _existing(folder: Path) -> Path:
    """The nearest existing folder (the scratch folder is made there, on OUT's file system)."""
    folder = folder.absolute()
    while not folder.is_dir():
        folder = folder.parent
    return folder


def _items(value: object) -> list[object]:
    if value is None:
        return []
    return list(value) if isinstance(value, (list, tuple)) else [value]


def _show(value: object) -> str:
    text = "(absent)" if value is None else repr(value)
    return text if len(text) <= 80 else text[:79] + "…"
