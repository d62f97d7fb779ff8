"""stereo_image_proc's disparity-node parameters, mapped once onto :class:`StereoMethod`.

The names, integer ranges (``from``, ``to``, ``step``) and defaults are those the ROS 2
``stereo_image_proc`` disparity node declares (image_pipeline 5.x, ``disparity_node.cpp``);
which matcher each one reaches is what its ``StereoProcessor`` sets: ``prefilter_size`` and
``texture_threshold`` only BM, ``disp12_max_diff``, ``P1``, ``P2`` and ``sgbm_mode`` only SGBM
(BM keeps OpenCV's ``disp12MaxDiff = -1``). ``uniqueness_ratio``, ``P1`` and ``P2`` are declared
as doubles but OpenCV takes integers, so a sweep uses whole numbers and the parameters YAML
writes them as doubles (a ROS 2 node refuses an integer for a double parameter).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from dispeval_ros.errors import ConfigurationError
from dispeval_ros.testbed.methods import SGBM_MODES, StereoMethod

FAMILIES = {"bm": 0, "sgbm": 1}
"""Method family → the node's ``stereo_algorithm`` value."""
ALGORITHM_PARAMETER = "stereo_algorithm"
DEFAULT_NODE_NAME = "disparity_node"
"""The disparity node's name in stereo_image_proc (the parameters YAML is keyed by it)."""

_MODE_NAMES = {value: name for name, value in SGBM_MODES.items()}


@dataclass(frozen=True)
class Parameter:
    """One node parameter: its range as declared, its default, where it goes in OpenCV."""

    name: str
    field: str
    """The :class:`StereoMethod` field it sets."""
    low: int
    high: int
    step: int
    default: int
    families: tuple[str, ...]
    short: str
    """Its tag in configuration names (``w5`` for a 5-px window)."""
    floating: bool = False
    """Declared as a double by the node."""
    note: str = ""
    """What else a value must be (said when refused)."""

    def check(self, value: object, where: str) -> int:
        """The value as an int, or one line naming ``where``, the parameter and its range."""
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigurationError(f"{where}: {self.name} must be a whole number, got {value!r}")
        if isinstance(value, float) and not value.is_integer():
            raise ConfigurationError(
                f"{where}: {self.name} must be a whole number (OpenCV takes an integer), "
                f"got {value!r}"
            )
        number = int(value)
        on_step = (number - self.low) % self.step == 0
        if not self.low <= number <= self.high or not on_step:
            steps = f" in steps of {self.step} from {self.low}" if self.step > 1 else ""
            raise ConfigurationError(
                f"{where}: {self.name} must be in [{self.low}, {self.high}]{steps}"
                f"{self.note}, got {number}"
            )
        return number


@dataclass(frozen=True)
class Configuration:
    """One point of a parameter space (offline or on a node): name, every value, matcher."""

    name: str
    values: dict[str, int]
    """Every parameter of the family (the node's defaults where the space sets none)."""
    method: StereoMethod


PARAMETERS: dict[str, Parameter] = {
    p.name: p
    for p in (
        Parameter("prefilter_size", "pre_filter_size", 5, 255, 2, 9, ("bm",), "pfs", note=" (odd)"),
        Parameter("prefilter_cap", "pre_filter_cap", 1, 63, 1, 31, ("bm", "sgbm"), "pfc"),
        Parameter(
            "correlation_window_size",
            "block_size",
            5,
            255,
            2,
            15,
            ("bm", "sgbm"),
            "w",
            note=" (odd)",
        ),
        Parameter("min_disparity", "min_disparity", -2048, 2048, 1, 0, ("bm", "sgbm"), "m"),
        Parameter(
            "disparity_range",
            "num_disparities",
            32,
            4096,
            16,
            64,
            ("bm", "sgbm"),
            "n",
            note=" (a multiple of 16)",
        ),
        Parameter("texture_threshold", "texture_threshold", 0, 10000, 1, 10, ("bm",), "t"),
        Parameter("speckle_size", "speckle_window_size", 0, 1000, 1, 100, ("bm", "sgbm"), "s"),
        Parameter("speckle_range", "speckle_range", 0, 31, 1, 4, ("bm", "sgbm"), "r"),
        Parameter("disp12_max_diff", "disp12_max_diff", 0, 128, 1, 0, ("sgbm",), "lr"),
        Parameter("sgbm_mode", "mode", 0, 3, 1, 0, ("sgbm",), "mode"),
        Parameter("uniqueness_ratio", "uniqueness_ratio", 0, 100, 1, 15, ("bm", "sgbm"), "u", True),
        # 0 is in the node's range, but OpenCV then falls back on its own penalties, which
        # StereoMethod (0 = 8·b², 32·b²) does not reproduce: a sweep gives them from 1.
        Parameter("P1", "p1", 1, 4000, 1, 200, ("sgbm",), "p1", True),
        Parameter("P2", "p2", 1, 4000, 1, 400, ("sgbm",), "p2", True),
    )
}
"""Every parameter a sweep may set, in the order the node declares them."""


def family_parameters(family: str) -> list[Parameter]:
    """The parameters that reach the matcher of ``family`` (``bm`` or ``sgbm``)."""
    return [p for p in PARAMETERS.values() if family in p.families]


def check_family(family: object, where: str) -> str:
    """``bm`` or ``sgbm`` (also given as the node's ``stereo_algorithm`` 0 or 1), else one line."""
    by_value = {value: name for name, value in FAMILIES.items()}
    if isinstance(family, int) and not isinstance(family, bool) and family in by_value:
        return by_value[family]
    if isinstance(family, str) and family.lower() in FAMILIES:
        return family.lower()
    raise ConfigurationError(
        f"{where}: family must be bm or sgbm ({ALGORITHM_PARAMETER} 0 or 1), got {family!r}"
    )


def check_parameter(name: object, family: str, where: str) -> Parameter:
    """The parameter called ``name``, if it reaches ``family``'s matcher; else one line."""
    parameter = PARAMETERS.get(str(name))
    if parameter is None:
        raise ConfigurationError(
            f"{where}: unknown parameter {name!r}; stereo_image_proc's are {', '.join(PARAMETERS)}"
        )
    if family not in parameter.families:
        other = parameter.families[0]
        raise ConfigurationError(
            f"{where}: {parameter.name} reaches only the {other.upper()} matcher "
            f"({ALGORITHM_PARAMETER} {FAMILIES[other]}); the {family} family ignores it"
        )
    return parameter


def full_values(family: str, values: Mapping[str, int]) -> dict[str, int]:
    """Every parameter of ``family``: the given values, the node's defaults for the others."""
    return {p.name: int(values.get(p.name, p.default)) for p in family_parameters(family)}


def stereo_method(name: str, family: str, values: Mapping[str, int]) -> StereoMethod:
    """The OpenCV matcher the node runs with ``values`` (defaults filled in), checked.

    Refuses (one line naming the configuration) what the node would run but not as configured:
    ``P2 ≤ P1`` (OpenCV then raises P2 to P1 + 1).
    """
    full = full_values(family, values)
    if family == "sgbm" and full["P2"] <= full["P1"]:
        raise ConfigurationError(
            f"configuration {name}: P2 must be greater than P1, got P1 = {full['P1']}, "
            f"P2 = {full['P2']}"
        )
    fields: dict[str, Any] = {PARAMETERS[key].field: value for key, value in full.items()}
    if "mode" in fields:
        fields["mode"] = _MODE_NAMES[fields["mode"]]
    try:
        return StereoMethod(name, "bm" if family == "bm" else "sgbm", **fields)
    except ConfigurationError as error:
        raise ConfigurationError(f"configuration {name}: {error}") from None


def ros_parameters(family: str, values: Mapping[str, int]) -> dict[str, int | float]:
    """The node's parameters for a configuration, typed as the node declares them."""
    full = full_values(family, values)
    typed: dict[str, int | float] = {ALGORITHM_PARAMETER: FAMILIES[family]}
    for key, value in full.items():
        typed[key] = float(value) if PARAMETERS[key].floating else value
    return typed


def params_document(
    node_name: str, family: str, values: Mapping[str, int]
) -> dict[str, dict[str, dict[str, int | float]]]:
    """``{node: {ros__parameters: {...}}}``: a ROS 2 parameters file (``--params-file``)."""
    return {node_name: {"ros__parameters": ros_parameters(family, values)}}
