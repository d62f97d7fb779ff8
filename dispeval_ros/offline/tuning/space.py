"""A parameter space: the file, its values checked, its configurations named and expanded.

A space file (YAML) names the family (``family: sgbm``, or ``bm``: stereo_algorithm 1 or 0)
and, under ``parameters``, per parameter one value, a list of values (a grid axis),
``{min, max, step}`` (every value of the range; ``step`` defaults to the node's) or
``{choices: [...]}``, e.g. ``{correlation_window_size: [5, 7, 9], uniqueness_ratio: {min: 5,
max: 15, step: 5}, sgbm_mode: {choices: [0, 2]}, disparity_range: 64}``.

Without a sample size the configurations are the whole grid (every combination); with one,
that many distinct combinations drawn with a seeded generator, listed in grid order. Every
configuration is checked before anything runs (each value in the node's range, ``P2 > P1``).
A configuration is named from the values that vary (``sgbm_w5_u10_mode0``), so its name says
what it is and is the same in every run of the space.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dispeval_ros.errors import ConfigurationError, InputError
from dispeval_ros.testbed.node_parameters import (
    PARAMETERS,
    Configuration,
    check_family,
    check_parameter,
    full_values,
    stereo_method,
)

MAX_GRID = 100_000
"""The most configurations a whole grid may hold (beyond: sample it with --samples)."""


@dataclass(frozen=True)
class Space:
    """A family and, per parameter, the values it may take (in the file's order)."""

    family: str
    axes: dict[str, list[int]]
    source: str = "the space"

    @property
    def size(self) -> int:
        """The number of combinations (the grid's configurations)."""
        return math.prod(len(values) for values in self.axes.values())

    def record(self) -> dict[str, Any]:
        """The space as the results database keeps it (a resume must give the same)."""
        return {"family": self.family, "axes": {k: list(v) for k, v in self.axes.items()}}

    def configurations(self, samples: int | None = None, seed: int = 0) -> list[Configuration]:
        """The whole grid, or ``samples`` distinct combinations drawn with ``seed``; checked."""
        size = self.size
        if samples is None:
            if size > MAX_GRID:
                raise ConfigurationError(
                    f"{self.source}: the grid holds {size} configurations (at most {MAX_GRID}); "
                    "draw some of them with --samples N"
                )
            indices = list(range(size))
        else:
            if samples < 2:
                raise ConfigurationError(f"--samples must be at least 2, got {samples}")
            indices = _draw(size, min(samples, size), seed)
        if len(indices) < 2:
            raise ConfigurationError(
                f"{self.source}: the space holds {len(indices)} configuration; give at least "
                "one parameter two or more values"
            )
        swept = [name for name, values in self.axes.items() if len(values) > 1]
        return [self._configuration(self._combination(i), swept) for i in indices]

    def _combination(self, index: int) -> dict[str, int]:
        """The ``index``-th combination in grid order (the last parameter varies fastest)."""
        values = {}
        for name, axis in reversed(list(self.axes.items())):
            index, position = divmod(index, len(axis))
            values[name] = axis[position]
        return {name: values[name] for name in self.axes}

    def _configuration(self, chosen: Mapping[str, int], swept: Sequence[str]) -> Configuration:
        tags = [f"{PARAMETERS[name].short}{chosen[name]}" for name in swept]
        name = "_".join([self.family, *tags])
        try:
            method = stereo_method(name, self.family, chosen)
        except ConfigurationError as error:
            raise ConfigurationError(f"{self.source}: {error}") from None
        return Configuration(name, full_values(self.family, chosen), method)


def _draw(size: int, count: int, seed: int) -> list[int]:
    """``count`` distinct indices below ``size``, drawn with ``seed``, in increasing order."""
    generator = np.random.default_rng(seed)
    if size <= 10 * MAX_GRID:
        return sorted(int(i) for i in generator.choice(size, size=count, replace=False))
    chosen: set[int] = set()
    while len(chosen) < count:
        chosen.add(int(generator.integers(size)))
    return sorted(chosen)


def _axis(name: str, spec: object, parameter: Any, where: str) -> list[int]:
    """The values of one parameter: a value, a list, ``{min, max, step}`` or ``{choices}``."""
    here = f"{where}: parameter {name}"
    if isinstance(spec, Mapping):
        keys = set(spec)
        if keys == {"choices"}:
            spec = spec["choices"]
        elif keys and keys <= {"min", "max", "step"} and {"min", "max"} <= keys:
            low = parameter.check(spec["min"], f"{here} (min)")
            high = parameter.check(spec["max"], f"{here} (max)")
            step = spec.get("step", parameter.step)
            if isinstance(step, bool) or not isinstance(step, int) or step < 1:
                raise ConfigurationError(f"{here}: step must be a whole number ≥ 1, got {step!r}")
            spec = list(range(low, high + 1, step))
            if not spec:
                raise ConfigurationError(f"{here}: the range is empty (min {low} > max {high})")
        else:
            raise ConfigurationError(
                f"{here}: expected a value, a list, {{min, max, step}} or {{choices: [...]}}, "
                f"got the keys {', '.join(map(str, spec)) or '(none)'}"
            )
    values = list(spec) if isinstance(spec, list | tuple) else [spec]
    if not values:
        raise ConfigurationError(f"{here}: no values (an empty list leaves the space empty)")
    checked = [parameter.check(value, here) for value in values]
    repeated = sorted({v for v in checked if checked.count(v) > 1})
    if repeated:
        raise ConfigurationError(f"{here}: value(s) {repeated} given twice")
    return checked


def space_from_document(document: object, source: str) -> Space:
    """Check a parsed space file (see the module docstring); one line naming what is wrong."""
    if not isinstance(document, Mapping):
        raise ConfigurationError(
            f"{source}: expected a mapping with 'family' and 'parameters', got "
            f"{type(document).__name__}"
        )
    unknown = sorted(set(map(str, document)) - {"family", "parameters"})
    if unknown:
        raise ConfigurationError(
            f"{source}: unknown key(s) {', '.join(unknown)} (a space has 'family' and 'parameters')"
        )
    if "family" not in document:
        raise ConfigurationError(f"{source}: no 'family' (bm or sgbm)")
    family = check_family(document["family"], source)
    parameters = document.get("parameters")
    if not isinstance(parameters, Mapping) or not parameters:
        raise ConfigurationError(
            f"{source}: the space is empty: 'parameters' must map parameter names to values"
        )
    axes = {}
    for name, spec in parameters.items():
        parameter = check_parameter(name, family, source)
        axes[parameter.name] = _axis(parameter.name, spec, parameter, source)
    return Space(family, axes, source)


def read_space(path: Path) -> Space:
    """Read and check a space file (YAML, or JSON, which YAML reads too)."""
    import yaml

    try:
        text = path.read_text(encoding="utf-8")
    except OSError as error:
        raise InputError(
            f"{path}: cannot read the space file ({error.strerror or error})"
        ) from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: the space file is not UTF-8 text") from None
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        problem = getattr(error, "problem", None) or "not YAML"
        raise InputError(f"{path}: cannot parse the space file{where}: {problem}") from None
    return space_from_document(document, str(path))


def stored_configurations(record: Mapping[str, Any]) -> dict[str, Configuration] | None:
    """The configurations a sweep's run record keeps (None: not a ``dispeval tune`` record).

    Rebuilt from the stored family and full values, as the sweep made them.
    """
    values, space = record.get("configurations"), record.get("space")
    if record.get("command") != "tune" or not isinstance(values, Mapping):
        return None
    family = check_family(space.get("family") if isinstance(space, Mapping) else None, "the run")
    return {
        name: Configuration(name, dict(full), stereo_method(name, family, full))
        for name, full in values.items()
    }
