"""``eval --confidence NAME=FILE``: a method's sparsification curves, AUC and AUSE by criterion.

Each confidence map is read with its own values and type (no disparity scaling; 8-bit images
stay ``uint8`` so their ties are exact) and handed with the method's estimate to
:class:`~dispeval_ros.core.confidence.ConfidenceScorer`; the frames' sums are pooled per method.
The CLI only reads, checks and prints: the numbers are :mod:`dispeval_ros.core.confidence`'s.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dispeval_ros.errors import ConfigurationError, DispevalError

if TYPE_CHECKING:
    from dispeval_ros.core.confidence import ConfidencePreset, ConfidenceSums
    from dispeval_ros.core.evaluator import Evaluator, Reference

OPTION = "--confidence"
PRESET_OPTION = "--confidence-preset"


def add_options(parser: argparse.ArgumentParser) -> None:
    """``--confidence NAME=FILE`` and ``--confidence-preset [NAME=]PRESET`` (off by default)."""
    group = parser.add_argument_group("confidence maps (sparsification, AUC, AUSE)")
    add_input_options(
        group, "NAME=FILE", "the confidence map of the estimate NAME (PNG 8/16 bit, PFM, NPY, "
        "TIFF; read unscaled)",
    )  # fmt: skip
    group.add_argument(
        "--confidence-plot",
        type=Path,
        metavar="FILE",
        help="also draw each method's sparsification curves and the oracle's on the criterion "
        "'all' as a PNG (needs matplotlib; --criteria must include all)",
    )


def add_input_options(group: argparse._ArgumentGroup, metavar: str, what: str) -> None:
    """``--confidence METAVAR`` (a file for eval, a topic for bags and live) and its presets."""
    from dispeval_ros.core.confidence import DEFAULT_PRESET, PRESETS

    group.add_argument(
        OPTION,
        action="append",
        default=[],
        metavar=metavar,
        help=f"{what}: its sparsification curves, AUC, optimal AUC and AUSE by criterion; "
        "repeatable",
    )
    group.add_argument(
        PRESET_OPTION,
        action="append",
        default=[],
        metavar="[NAME=]PRESET",
        help=f"the confidences' convention: {', '.join(PRESETS)}, or higher:LOW:HIGH / "
        f"lower:LOW:HIGH (default {DEFAULT_PRESET}); NAME=PRESET for one method only",
    )


def preset_texts(args: argparse.Namespace) -> tuple[str, dict[str, str]]:
    """``--confidence-preset`` as (the default for every method, {method: its own})."""
    from dispeval_ros.core.confidence import DEFAULT_PRESET

    default, own = DEFAULT_PRESET, {}
    for spec in args.confidence_preset:
        if "=" in spec:
            name, text = _split(spec, PRESET_OPTION)
            own[name] = text
        else:
            default = spec
    return default, own


def stream_presets(args: argparse.Namespace, confidences: Mapping[str, str]) -> dict[str, str]:
    """Each ``--confidence`` method's preset text (others named are the configuration's to refuse).

    Presets without ``--confidence``: one line.
    """
    if args.confidence_preset and not confidences:
        raise ConfigurationError(f"{PRESET_OPTION} needs {OPTION} NAME=TOPIC")
    default, own = preset_texts(args)
    return {name: own.get(name, default) for name in confidences} | own


def _split(spec: str, option: str) -> tuple[str, str]:
    name, equals, value = spec.partition("=")
    if not equals or not name or not value:
        raise ConfigurationError(f"{option} '{spec}' is not NAME=VALUE")
    return name, value


def check_options(args: argparse.Namespace) -> None:
    """Refuse ``--confidence`` with ``--protocol`` (one line)."""
    if args.confidence and args.protocol is not None:
        raise ConfigurationError(f"{OPTION} does not apply with --protocol (drop one of them)")


def configuration(args: argparse.Namespace) -> dict[str, object]:
    """The provenance's entry (nothing without ``--confidence``)."""
    if not args.confidence:
        return {}
    return {"confidence": {"maps": list(args.confidence), "presets": list(args.confidence_preset)}}


def plan(args: argparse.Namespace, methods: Sequence[str]) -> dict[str, tuple[Path, Any]]:
    """Each method's confidence file and preset (one line if a name or preset is wrong)."""
    from dispeval_ros.core.confidence import parse_preset

    if not args.confidence:
        if args.confidence_preset or args.confidence_plot is not None:
            raise ConfigurationError(
                "--confidence-preset and --confidence-plot need --confidence NAME=FILE"
            )
        return {}
    default_text, texts = preset_texts(args)
    default = parse_preset(default_text)
    own = {name: parse_preset(text) for name, text in texts.items()}
    chosen: dict[str, tuple[Path, ConfidencePreset]] = {}
    for spec in args.confidence:
        name, path = _split(spec, OPTION)
        if name not in methods:
            raise ConfigurationError(
                f"{OPTION} {spec}: no estimate is named '{name}' (estimates: {', '.join(methods)})"
            )
        if name in chosen:
            raise ConfigurationError(f"{OPTION}: two confidence maps for '{name}'")
        chosen[name] = (Path(path), own.pop(name, default))
    if own:
        raise ConfigurationError(
            f"--confidence-preset names no --confidence method: {', '.join(sorted(own))}"
        )
    return chosen


def score_one(
    evaluator: Evaluator,
    preset: ConfidencePreset,
    reference: Reference,
    estimate: np.ndarray,
    path: Path,
) -> ConfidenceSums:
    """One frame's sums of one method (errors name the confidence file, one line)."""
    from dispeval_ros.core.confidence import ConfidenceScorer
    from dispeval_ros.io.files import read_confidence

    try:
        return ConfidenceScorer(evaluator, preset).score(reference, estimate, read_confidence(path))
    except DispevalError as error:
        message = str(error)
        raise type(error)(message if str(path) in message else f"{path}: {message}") from None


def summaries(pooled: Mapping[str, ConfidenceSums]) -> dict[str, object]:
    """The JSON ``confidence`` entry: each method's pooled sums, summarised."""
    return {name: one.summary() for name, one in pooled.items()}


def plot(args: argparse.Namespace, pooled: Mapping[str, ConfidenceSums]) -> str | None:
    """Write ``--confidence-plot FILE`` (the 'all' criterion); the line saying so, if asked."""
    if args.confidence_plot is None:
        return None
    from dispeval_ros.report.confidence import sparsification_figure

    sparsification_figure(pooled, args.confidence_plot)
    return f"sparsification curves: {args.confidence_plot}"


def text(summary: Mapping[str, Any]) -> str:
    """A table per method: criterion, measure, AUC, AUC_opt, AUSE, ratio, density."""
    from dispeval_ros.cli.output import table

    blocks = []
    for method, criteria in summary.items():
        rows = [
            [criterion, f"{measure} [{curve['unit']}]",
             *(curve[key] for key in ("auc", "auc_opt", "ause", "ratio")), entry["density"]]
            for criterion, entry in criteria.items()
            for measure, curve in entry.items()
            if isinstance(curve, dict)
        ]  # fmt: skip
        header = ["criterion", "measure", "AUC", "AUC_opt", "AUSE", "ratio", "density"]
        blocks.append(f"confidence of {method}:\n" + table(header, rows))
    return "\n\n".join(blocks)
