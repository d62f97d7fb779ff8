"""The measure registry is the one source: every front end lists it, the kernels' layout is it.

Guards of issue 22: a measure added to :mod:`dispeval_ros.core.registry` appears in the CLI
help, the ROS parameter description, the report's recipes, the score-vector labels and the
objective defaults, and its derivation from the sums equals the independent formulas below.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from dispeval_ros.cli.main import build_parser
from dispeval_ros.core import kernels, measures, objectives, registry
from dispeval_ros.core.kernels import layout
from dispeval_ros.report import html
from dispeval_ros.report.recipes import measure_recipe, recipe_values
from dispeval_ros.ros.params import EVALUATOR_PARAMETERS
from dispeval_ros.stream.vectors import vector_labels

THRESHOLDS = np.array([1.0, 0.5, 2.0, 4.0, *[math.inf] * (registry.MAX_THRESHOLDS - 4)])
"""δ = 1 and the default bad-x thresholds."""


def concrete(name: str) -> str:
    """A registry name as a measure one can score (a family at one of its members)."""
    return {"bad_X": "bad_2", "aNN": "a90"}.get(name, name)


def listed(text: str) -> list[str]:
    """The registry's measures missing from a help text (words, commas or spaces apart)."""
    words = set(re.split(r"[\s,:()]+", text))
    return [name for name in registry.MEASURE_NAMES if name not in words]


def test_cli_measures_help_lists_every_measure() -> None:
    parser = build_parser()
    subparsers = next(a for a in parser._actions if a.choices and "eval" in a.choices)
    option = next(
        a for a in subparsers.choices["eval"]._actions if "--measures" in a.option_strings
    )
    assert listed(option.help or "") == []


def test_ros_measures_parameter_lists_every_measure() -> None:
    [param] = [p for p in EVALUATOR_PARAMETERS if p.name == "measures"]
    assert listed(param.constraints) == []


def test_report_has_a_recipe_for_every_measure() -> None:
    """And the page's script interprets every kind the registry uses."""
    script = html.report_script()
    for name in registry.MEASURE_NAMES:
        recipe = measure_recipe(concrete(name), THRESHOLDS)
        assert recipe["kind"] in {m.kind for m in registry.MEASURES}
        assert f"'{recipe['kind']}'" in script or recipe["kind"] == registry.RATIO, recipe
        assert recipe["higher"] == (name in measures.HIGHER_IS_BETTER)


def test_vector_labels_carry_every_measure_where_it_applies() -> None:
    chosen = [concrete(name) for name in registry.MEASURE_NAMES]
    labels = vector_labels(["all", "gtfree:all"], chosen)
    for name in chosen:
        for criterion in ("all", "gtfree:all"):
            assert (f"{criterion}/{name}" in labels) == measures.applies(name, criterion), name


def test_objective_defaults_follow_the_registry() -> None:
    assert objectives.DEFAULT_OBJECTIVE_MEASURES == ("sze", "bmpre")
    assert objectives.GT_FREE_OBJECTIVE == "vpe"
    assert measures.HIGHER_IS_BETTER == ("density",)
    assert measures.GT_FREE_MEASURES == ("vpe", "lrc")
    assert measures.DEPTH_MEASURES == ("mae_z", "rmse_z", "absrel_z", "irmse")
    assert set(measures.DEFAULT_MEASURES) <= {
        *registry.MEASURE_NAMES,
        *(f"bad_{t:g}" for t in measures.DEFAULT_BAD_THRESHOLDS),
        *(f"a{q}" for q in measures.DEFAULT_QUANTILES),
    }


def test_every_measure_is_described() -> None:
    for measure in (*registry.MEASURES, registry.POINTS):
        assert measure.unit, measure
        assert measure.description, measure
        assert measure.needs in (registry.NEEDS_GT, registry.NEEDS_IMAGES, registry.NEEDS_NONE)
        assert measure.direction in (registry.LOWER, registry.HIGHER)
        for field in (measure.num, measure.den):
            assert field is None or field in registry.SUM_FIELDS, measure
        assert measures.measure_unit(concrete(measure.name)) == measure.unit


def test_kernel_layout_is_the_registry_layout() -> None:
    constants = {
        name: value
        for name, value in vars(layout).items()
        if name.startswith("FIELD_") and name != "FIELD_COUNT"
    }
    assert constants  # every constant names a distinct field, at the registry's position
    assert sorted(constants.values()) == sorted(set(constants.values()))
    assert kernels.FIELD_COUNT == len(registry.SUM_FIELDS) == measures.FIELDS
    assert kernels.MAX_THRESHOLDS == registry.MAX_THRESHOLDS
    bad = registry.field_index("bad_count_0")
    named = set(constants.values())
    for index, field in enumerate(registry.SUM_FIELDS):
        assert index in named or bad < index < bad + registry.MAX_THRESHOLDS, field
    for name, value in constants.items():
        assert getattr(kernels, name) == value


def _reference(name: str, s: dict[str, float]) -> float:
    """Today's formulas, written out independently of the registry."""

    def ratio(num: float, den: float, scale: float = 1.0) -> float:
        return scale * num / den if den > 0 else math.nan

    e = s["n_eval"]
    return {
        "bmp": ratio(s["bad_count_0"], e, 100.0),
        "bmp_count": s["bad_count_0"],
        "bad_2": ratio(s["bad_count_2"], e, 100.0),
        "mae": ratio(s["sum_e"], e),
        "mse": ratio(s["sum_e2"], e),
        "rmse": math.sqrt(ratio(s["sum_e2"], e)),
        "mre": ratio(s["sum_rel"], e),
        "sze": s["sze"],
        "sze_mean": ratio(s["sze"], e),
        "bmpre": s["bmpre"],
        "bmpre_mean": ratio(s["bmpre"], e),
        "d1": ratio(s["d1_count"], e, 100.0),
        "density": ratio(s["n_valid"], s["n"]),
        "mae_z": ratio(s["sum_ez"], e),
        "rmse_z": math.sqrt(ratio(s["sum_ez2"], e)),
        "absrel_z": ratio(s["sum_relz"], e),
        "irmse": 1000.0 * math.sqrt(ratio(s["sum_iz2"], e)),
        "vpe": ratio(s["sum_vpe"], s["n_vpe"]),
        "lrc": ratio(s["lrc_count"], s["n_lrc"], 100.0),
    }[name]


@pytest.mark.parametrize("empty", [False, True])
def test_recipes_from_sums_equal_the_formulas(empty: bool) -> None:
    """Python derivations exactly; the page's recipes (evaluated as the script does) to 1 ulp."""
    rng = np.random.default_rng(22)
    rows = rng.random((50, len(registry.SUM_FIELDS))) * 100
    if empty:
        rows[:, registry.field_index("n_eval")] = 0
        rows[:, registry.field_index("n")] = 0
        rows[:, registry.field_index("n_vpe")] = 0
        rows[:, registry.field_index("n_lrc")] = 0
    for name in (concrete(n) for n in registry.MEASURE_NAMES):
        if measures.quantile_level(name) is not None:
            continue  # stored per frame, not derived from sums
        page = recipe_values(measure_recipe(name, THRESHOLDS), rows)
        for row, from_page in zip(rows, page, strict=True):
            expected = _reference(name, dict(zip(registry.SUM_FIELDS, row.tolist(), strict=True)))
            got = measures.measure_from_sums(name, row, THRESHOLDS)
            assert got == expected or (math.isnan(got) and math.isnan(expected)), name
            assert from_page == pytest.approx(expected, rel=1e-15, nan_ok=True), name


def test_script_parts_are_the_asset_files() -> None:
    """Every part of the page's script is joined, once, in the listed order."""
    folder = Path(html.__file__).parent / "assets" / "js"
    assert sorted(html.SCRIPT_PARTS) == sorted(p.stem for p in folder.glob("*.js"))
    assert len(set(html.SCRIPT_PARTS)) == len(html.SCRIPT_PARTS)
    script = html.report_script()
    assert script.startswith("/* dispeval report")
    assert script.rstrip().endswith("})();")


def test_the_report_reads_units_from_the_registry_not_its_own_words() -> None:
    """The page's unit words come from the recipes (``measure_unit``), the relative SZE too."""
    from dispeval_ros.report.recipes import measure_recipe

    thresholds = np.array([1.0])
    sze = measure_recipe("sze", thresholds)
    assert sze["unit"] == measures.measure_unit("sze")
    assert sze["relative_unit"] == measures.measure_unit("sze", relative=True)
    assert "relative_unit" not in measure_recipe("bmp", thresholds)  # no camera changes nothing
    script = html.report_script()
    assert "recipe.relative_unit" in script
    assert not re.search(r"return '[^']*relative[^']*'", script)  # no unit word of its own
