"""``dispeval eval --protocol P``: a benchmark's official numbers, in its own layout."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from dispeval_ros.cli.common import given
from dispeval_ros.cli.output import print_json, wrapped
from dispeval_ros.cli.summary import fitted_tables, models_text
from dispeval_ros.core.protocols import PROTOCOLS, Protocol, get_protocol
from dispeval_ros.errors import ConfigurationError

if TYPE_CHECKING:
    from dispeval_ros.offline.benchmark import BenchmarkRun


def _in_tree_results() -> str:
    """Where ``--est NAME`` alone looks, from the protocols' own result layouts."""
    paths: dict[str, list[str]] = {}
    for protocol in PROTOCOLS.values():
        for path in protocol.results.scene:
            paths.setdefault(path.format(method="NAME"), []).append(protocol.name)
    return "; ".join(
        f"{path} in each {'/'.join(names)} scene folder" for path, names in paths.items()
    )


def add_options(parser: argparse.ArgumentParser) -> None:
    """``--protocol`` and the files a single protocol frame may need."""
    group = parser.add_argument_group(
        "official protocols (numbers as the benchmark's own tool prints them)"
    )
    group.add_argument(
        "--protocol",
        choices=list(PROTOCOLS),
        help="evaluate as the benchmark does: regions, measures, invalid handling and the "
        "official tool's float32 arithmetic; --scene is then a dataset tree (or one scene) and "
        "--est NAME=RESULTS_DIR a method's results laid out as the benchmark expects "
        f"(--est NAME alone: {_in_tree_results()}; every layout: README 'Reproduce a benchmark'); "
        "--criteria, --measures, --missing, --delta, --mu and --depth-ranges do not apply and "
        "are refused",
    )
    group.add_argument(
        "--gt-noc", type=Path, help="KITTI: the non-occluded GT (disp_noc) of a --gt frame"
    )
    group.add_argument("--obj-map", type=Path, help="KITTI 2015: the obj_map of a --gt frame")
    group.add_argument(
        "--summary-only", action="store_true", help="with --protocol: no per-frame tables"
    )


MOVED_SHOWN = 10


def _estimates(specs: list[str]) -> dict[str, Path | None]:
    chosen: dict[str, Path | None] = {}
    for spec in specs:
        if "=" in spec:
            name, _, where = spec.partition("=")
            if not name:
                raise ConfigurationError(f"empty method name in --est '{spec}'")
            path: Path | None = Path(where)
        elif Path(spec).exists():
            name, path = Path(spec).stem, Path(spec)
        else:
            name, path = spec, None
        if name in chosen:
            raise ConfigurationError(f"two methods are named '{name}'; use NAME=PATH")
        chosen[name] = path
    return chosen


def run(args: argparse.Namespace) -> int:
    """Score every frame of the dataset for each method; print the benchmark's tables."""
    from dispeval_ros.offline.benchmark import evaluate_benchmark, evaluate_frames, single_frame

    protocol = get_protocol(args.protocol)
    _refuse_unused_options(args, protocol)
    estimates = _estimates(args.est)
    if args.scene is not None:
        if args.gt is not None:
            raise ConfigurationError("give either --scene or --gt, not both")
        run_result = evaluate_benchmark(protocol, args.scene, estimates)
    elif args.gt is not None:
        masks = dict(spec.partition("=")[::2] for spec in args.mask)
        unknown = set(masks) - {"nonocc"}
        if unknown:
            raise ConfigurationError(
                f"--mask {', '.join(sorted(unknown))}: with --protocol only nonocc=FILE "
                "(mask0nocc.png) is used"
            )
        missing = [name for name, where in estimates.items() if where is None]
        if missing:
            raise ConfigurationError(f"--est {missing[0]}: with --gt give NAME=FILE")
        frame = single_frame(
            args.gt,
            gt_noc=args.gt_noc,
            mask=Path(masks["nonocc"]) if "nonocc" in masks else None,
            obj_map=args.obj_map,
            calib=args.calib,
        )
        run_result = evaluate_frames(protocol, [frame], estimates, str(args.gt))
    else:
        raise ConfigurationError("give the ground truth with --scene DIR or --gt FILE")
    if args.json:
        print_json(run_result.to_dict())
        return 0
    print(report_text(run_result, per_frame=not args.summary_only))
    return 0


#: What a benchmark's protocol uses instead of each project option it overrides.
PROTOCOL_OWN = {
    "criteria": "its own regions",
    "measures": "its own measures",
    "missing": "its own invalid-estimate handling",
    "delta": "its own thresholds",
    "mu": "its own measures (no SZE)",
    "depth_ranges": "its own regions",
}


def _refuse_unused_options(args: argparse.Namespace, protocol: Protocol) -> None:
    """The project's evaluation options never set a benchmark's numbers: refused if given.

    Whatever the value: ``--delta 1`` (the default written out) is refused as ``--delta 2``.
    """
    unused = given(args, *PROTOCOL_OWN)
    if unused:
        raise ConfigurationError(
            f"{unused[0]} does not apply with --protocol: {protocol.name} uses "
            f"{PROTOCOL_OWN[unused[0][2:].replace('-', '_')]} (drop the option)"
        )


def _cell(protocol: Protocol, column: str, value: float) -> str:
    if value is None or math.isnan(value):
        return "-"
    if math.isinf(value):
        return "inf"
    return f"{value:.2f}" + (" %" if column in protocol.percent else "")


def _text_table(header: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = [
        "  ".join(
            h.ljust(w) if i == 0 else h.rjust(w)
            for i, (h, w) in enumerate(zip(header, widths, strict=True))
        )
    ]
    lines.append("  ".join("-" * w for w in widths))
    for row in rows:
        lines.append(
            "  ".join(
                c.ljust(w) if i == 0 else c.rjust(w)
                for i, (c, w) in enumerate(zip(row, widths, strict=True))
            )
        )
    return "\n".join(lines)


def report_text(run_result: BenchmarkRun, per_frame: bool = True) -> str:
    """The human report: per-frame tables, the summary table, the A* Groups, provenance."""
    protocol: Protocol = run_result.protocol
    provenance = run_result.provenance
    files = run_result.files
    blocks = [
        wrapped(
            f"{protocol.title} — protocol '{protocol.name}' as {protocol.tool}\n"
            f"dataset: {run_result.dataset} ({len(run_result.frames)} frames)\n"
            f"float32 as the official tool: {protocol.float32}\n"
            f"dispeval_ros {provenance.get('version')}, configuration sha256 "
            f"{str(provenance.get('configuration_sha256'))[:16]}…, {len(files)} input files "
            "hashed (sha256 of each in --json)"
        )
    ]
    notes = [f"note: {note}" for note in run_result.notes()]
    if run_result.moved:
        notes.append(
            f"float32: the official tool's arithmetic moves {len(run_result.moved)} printed "
            "value(s); shown as the tool prints them (exact arithmetic in brackets):"
        )
        for moved in run_result.moved[:MOVED_SHOWN]:
            notes.append(
                f"  {moved.method} {moved.frame} {moved.region} {moved.column}: "
                f"{_cell(protocol, moved.column, moved.official)} "
                f"({_cell(protocol, moved.column, moved.exact)})"
            )
        if len(run_result.moved) > MOVED_SHOWN:
            notes.append(f"  … {len(run_result.moved) - MOVED_SHOWN} more in --json")
    else:
        notes.append("float32: the official arithmetic moves no printed value here")
    blocks.append("\n".join(notes))
    columns = list(protocol.columns)
    if per_frame:
        for method, frames in run_result.results.items():
            rows = [
                [f"{f.frame} {region}", *(_cell(protocol, c, f.values[region][c]) for c in columns)]
                for f in frames
                for region in protocol.regions
                if region in f.values
            ]
            blocks.append(
                f"method {method}: per frame\n"
                + fitted_tables(["frame region", *columns], rows, keep=1, render=_text_table)
            )
    for region in protocol.regions:
        rows = [
            [method, *(_cell(protocol, c, summary[region][c]) for c in columns)]
            for method, summary in run_result.summary.items()
            if region in summary
        ]
        if rows:
            blocks.append(
                wrapped(f"summary, region {region} ({protocol.summary})")
                + "\n"
                + fitted_tables(["method", *columns], rows, keep=1, render=_text_table)
            )
    if run_result.models is not None:
        blocks.append(models_text(run_result.models, run_result.objectives))
    return "\n\n".join(blocks)


def add_stream_option(parser: argparse.ArgumentParser) -> None:
    """``--protocol`` for stream commands: a benchmark's measures as a preset."""
    parser.add_argument(
        "--protocol",
        choices=list(PROTOCOLS),
        help="use a benchmark's measures, thresholds and invalid-estimate handling over 'all' "
        "(sets what --criteria, --measures, --missing, --objective-measures would: they are "
        "refused with it; exact arithmetic: "
        "bags carry no official masks, see README 'Reproduce a benchmark')",
    )


#: What a stream preset sets in place of each option it replaces (refused when written out).
STREAM_PRESET_SETS = {
    "criteria": "the criteria",
    "measures": "the measures",
    "missing": "the invalid-estimate handling",
    "objective_measures": "the objective measures",
}


def apply_stream_preset(args: argparse.Namespace) -> dict[str, object]:
    """Set the options a ``--protocol`` preset fixes; the preset's record (empty without one)."""
    if getattr(args, "protocol", None) is None:
        return {}
    from dispeval_ros.core.objectives import default_objective_measures
    from dispeval_ros.core.protocols import stream_preset

    replaced = given(args, *STREAM_PRESET_SETS)
    if replaced:
        raise ConfigurationError(
            f"{replaced[0]} does not apply with --protocol {args.protocol}: the preset sets "
            f"{STREAM_PRESET_SETS[replaced[0][2:].replace('-', '_')]} (drop the option)"
        )
    preset = stream_preset(args.protocol)
    args.criteria = list(preset.criteria)
    args.measures = list(preset.measures)
    args.missing = preset.missing
    args.objective_measures = default_objective_measures(preset.measures)
    return {"protocol": args.protocol, "protocol_preset": preset.record()}


def preset_note(protocol: str) -> str:
    """One line saying what a stream preset does not reproduce of the official tool."""
    from dispeval_ros.core.protocols import stream_preset

    return f"protocol {protocol} (stream preset): {stream_preset(protocol).differs}"
