"""What a sweep leaves for people: the table of every configuration, and parameters files.

``tune.csv`` holds one row per configuration (A* group, reduced or not, every node parameter,
the shown measures); ``params/NAME.yaml`` is the ROS 2 parameters file of each group-1
configuration for stereo_image_proc's disparity node, ready for ``--params-file``;
``figures/`` the sweep in parallel coordinates and each measure's sensitivity to each
parameter.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from dispeval_ros.core import ModelResult, Scores, evaluate_models
from dispeval_ros.core.objectives import default_objective_measures
from dispeval_ros.errors import InputError
from dispeval_ros.offline.tuning.space import Configuration, stored_configurations
from dispeval_ros.summary import ScoreSource, objective_table
from dispeval_ros.testbed.node_parameters import params_document

TABLE_CSV = "tune.csv"
PARAMS_FOLDER = "params"
FIGURES_FOLDER = "figures"
"""The sweep's figures (:mod:`dispeval_ros.report.sweep`), where matplotlib is installed."""


@dataclass(frozen=True)
class TuneRow:
    """One configuration as the tables show it."""

    configuration: Configuration
    group: int
    reduced: bool
    rank: float
    measures: dict[str, float]


def tune_rows(
    configurations: Sequence[Configuration],
    models: ModelResult,
    pooled: Mapping[str, Scores],
    shown: Sequence[tuple[str, str]],
) -> list[TuneRow]:
    """Every configuration, best first (A* group, then Middlebury rank, then name).

    ``shown`` lists the (criterion, measure) pairs whose value over every scene (``pooled``,
    the stored sums of all sequences) goes beside the parameters.
    """
    rows = []
    for configuration in configurations:
        name = configuration.name
        scores = pooled.get(name)
        measures = {
            f"{measure} ({criterion})": (
                scores[criterion][measure]
                if scores is not None and criterion in scores.criteria
                else math.nan
            )
            for criterion, measure in shown
        }
        rows.append(
            TuneRow(
                configuration,
                models.groups[name],
                name in models.reduced,
                models.middlebury[name],
                measures,
            )
        )
    rows.sort(key=lambda r: (r.group, r.rank, r.configuration.name))
    return rows


class SweepSource(ScoreSource, Protocol):
    """A database, or a multi-fidelity run's view of its last round: scores and the record."""

    def config(self) -> Mapping[str, Any]: ...  # noqa: D102


@dataclass(frozen=True)
class SweepResult:
    """A sweep's database read back: its configurations ranked, the models, the objectives."""

    rows: list[TuneRow]
    models: ModelResult
    objectives: list[str]


def stored_sweep(
    store: SweepSource, measures: Sequence[str] | None = None, granularity: str = "sequence"
) -> SweepResult | None:
    """The rows, models and objectives of a ``dispeval tune`` database (None: not one).

    ``store``: the database, or a multi-fidelity run's view of its last round. The models as
    ``dispeval models`` makes them from the stored frames (``measures``,
    ``granularity``: the objectives; default SZE and BMPRE); beside the parameters, each
    objective measure over every scene on the first stored criterion (``all`` by default).
    """
    configurations = stored_configurations(store.config())
    if configurations is None:
        return None
    methods, objectives, matrix = objective_table(store, measures, granularity)
    models = evaluate_models(methods, matrix)
    pooled = store.sequence_scores()
    first = next(iter(pooled.values()))
    wanted = measures or default_objective_measures(first.measures)
    shown = [(first.criteria[0], m) for m in wanted]
    rows = tune_rows([configurations[m] for m in methods], models, pooled, shown)
    return SweepResult(rows, models, objectives)


def write_table(folder: Path, rows: Sequence[TuneRow]) -> Path:
    """Write ``folder/tune.csv`` (floats in round-trip form, empty for NaN)."""
    path = folder / TABLE_CSV
    parameters = list(rows[0].configuration.values) if rows else []
    measures = list(rows[0].measures) if rows else []
    try:
        with open(path, "w", newline="", encoding="utf-8") as handle:
            writer = csv.writer(handle)
            writer.writerow(["method", "group", "reduced", "avg_rank", *parameters, *measures])
            for row in rows:
                values = row.configuration.values
                writer.writerow(
                    [
                        row.configuration.name,
                        row.group,
                        int(row.reduced),
                        repr(float(row.rank)),
                        *(values[p] for p in parameters),
                        *(
                            repr(float(v)) if math.isfinite(v) else ""
                            for v in row.measures.values()
                        ),
                    ]
                )
    except OSError as error:
        raise InputError(f"{path}: cannot write ({error.strerror or error})") from None
    return path


def write_params_files(
    folder: Path, family: str, rows: Sequence[TuneRow], node_name: str
) -> list[Path]:
    """Write ``folder/params/NAME.yaml`` for every group-1 configuration; the files written."""
    import yaml

    target = folder / PARAMS_FOLDER
    written = []
    try:
        target.mkdir(parents=True, exist_ok=True)
        for row in rows:
            if row.group != 1:
                continue
            name = row.configuration.name
            path = target / f"{name}.yaml"
            document = params_document(node_name, family, row.configuration.values)
            header = (
                f"# dispeval tune: {name}, A* group 1"
                + (", in the reduced front" if row.reduced else "")
                + f"\n# ros2 run stereo_image_proc disparity_node --ros-args --params-file {name}.yaml\n"
            )
            path.write_text(header + yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
            written.append(path)
    except OSError as error:
        raise InputError(f"{target}: cannot write ({error.strerror or error})") from None
    return written
