"""``dispeval tune``: sweep OpenCV stereo parameters on scenes, judge them by A* Groups."""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path
from typing import Any

from dispeval_ros.cli import common
from dispeval_ros.cli.output import plural, print_json, table, wrapped
from dispeval_ros.cli.progress import Progress
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.offline.tuning.fidelity import DEFAULT_KEEP
from dispeval_ros.offline.tuning.sweep import DEFAULT_CHUNK
from dispeval_ros.stream.tuning import NODE_TIMEOUT
from dispeval_ros.testbed.node_parameters import DEFAULT_NODE_NAME

HELP = "sweep the parameters of an OpenCV stereo matcher on scenes and rank them by A* Groups"
SHOWN_ROWS = 20
"""Configurations printed (best first); tune.csv holds them all."""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``tune``."""
    parser = subparsers.add_parser(
        "tune",
        help=HELP,
        description=HELP + ". Each configuration of the --space file (stereo_image_proc's "
        "parameter names) is a method: its maps of every scene frame are scored as 'dispeval "
        "eval' scores them, into DIR/results.sqlite unit by unit (resumable); then A* Groups "
        "and the front reduction over the objectives, a table with the parameter values "
        "(DIR/tune.csv) and, for each group-1 configuration, DIR/params/NAME.yaml for the "
        "disparity node's --params-file.",
    )
    parser.add_argument(
        "--space",
        type=Path,
        required=True,
        metavar="FILE.yaml",
        help="the parameter space: family (bm or sgbm) and per parameter a value, a list, "
        "{min, max, step} or {choices: [...]}",
    )
    parser.add_argument(
        "--scene",
        type=Path,
        action="append",
        required=True,
        metavar="DIR",
        help="a dataset scene folder (images, GT, masks, camera), or a dataset tree (every scene "
        "folder in it); repeat for several: each scene is one sequence",
    )
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="results folder")
    parser.add_argument(
        "--samples",
        type=int,
        metavar="N",
        help="score N distinct configurations drawn at random from the space (default: all)",
    )
    parser.add_argument("--seed", type=int, default=0, help="the seed of --samples (default 0)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the units on a Dask cluster: tcp://HOST:PORT of its scheduler (the workers "
        "must see the scene folders), or local:N for a local cluster of N worker processes",
    )
    parser.add_argument(
        "--chunk",
        type=int,
        default=DEFAULT_CHUNK,
        metavar="N",
        help=f"configurations per unit of work (default {DEFAULT_CHUNK})",
    )
    parser.add_argument(
        "--fidelity",
        type=int,
        metavar="R",
        help="multi-fidelity in R ≥ 2 rounds: round r scores the surviving configurations on "
        "the first ⌈N·2^(r−R)⌉ of the scenes' N frames (frame 0 of every scene, then frame 1, "
        "…; the last round all), keeps whole A* groups from group 1 on until --keep of them is "
        "kept; the models are those of the configurations of the last round",
    )
    parser.add_argument(
        "--keep",
        type=float,
        metavar="F",
        help=f"with --fidelity: the fraction of a round's configurations kept at least, in whole "
        f"A* groups (default {DEFAULT_KEEP})",
    )
    parser.add_argument(
        "--resume", action="store_true", help="continue an interrupted run in --out"
    )
    parser.add_argument(
        "--node-name",
        default=DEFAULT_NODE_NAME,
        help=f"the node the parameters files are for (default {DEFAULT_NODE_NAME})",
    )
    parser.add_argument(
        "--node",
        metavar="NAME",
        help="sweep this running ROS 2 disparity node instead of OpenCV here (stereo_image_proc's "
        "interface; needs rclpy): each configuration is set through its parameter services, "
        "the scene frames are sent to its inputs and its disparity maps scored; its parameters "
        "are restored at the end; one unit per configuration",
    )
    parser.add_argument(
        "--node-namespace",
        metavar="NS",
        help="the namespace of the node's topics (default: the node's own namespace)",
    )
    parser.add_argument(
        "--timeout",
        type=float,
        default=None,
        metavar="S",
        help="with --node: seconds to wait for the node's map of a frame before counting it "
        f"dropped (default {NODE_TIMEOUT:g})",
    )
    common.add_evaluation_options(parser)
    common.add_objective_options(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.set_defaults(run=run)


def _check_numbers(args: argparse.Namespace) -> None:
    from dispeval_ros.offline.executors import check_engine

    check_engine(args.jobs, args.scheduler)
    if args.chunk < 1:
        raise ConfigurationError(f"--chunk must be at least 1, got {args.chunk}")
    if args.node is None:
        if args.node_namespace is not None or args.timeout is not None:
            raise ConfigurationError("--node-namespace and --timeout apply to --node only")
    elif args.jobs != 1 or args.scheduler is not None:
        raise ConfigurationError("--node drives one node: --jobs and --scheduler do not apply")
    elif args.fidelity is not None:
        raise ConfigurationError("--fidelity rounds are for the offline sweep, not --node")
    if args.timeout is not None and not args.timeout > 0:
        raise ConfigurationError(
            f"--timeout must be a positive number of seconds, got {args.timeout}"
        )
    if args.fidelity is not None and args.fidelity < 2:
        raise ConfigurationError(
            f"--fidelity must be at least 2 rounds, got {args.fidelity} (one round is the full "
            "sweep: leave --fidelity out)"
        )
    if args.keep is not None and args.fidelity is None:
        raise ConfigurationError(
            "--keep is the fraction kept by --fidelity rounds; give --fidelity R"
        )
    if args.keep is not None and not 0 < args.keep < 1:
        raise ConfigurationError(f"--keep must be a fraction between 0 and 1, got {args.keep}")
    if not args.node_name or any(c in args.node_name for c in " \t\n:"):
        raise ConfigurationError(f"--node-name must be a ROS node name, got {args.node_name!r}")


def _connect(args: argparse.Namespace, family: str, loaded: dict[int, Any], start: Any) -> Any:
    """The connection to ``--node`` (checked when opened: there, its parameters, ``start``)."""
    try:
        from dispeval_ros.ros.tune_node import NodeSweep
    except ImportError as error:
        raise ConfigurationError(
            f"tune --node needs ROS 2's rclpy and its messages ({error}); source a ROS 2 "
            "install (see README 'ROS 2 nodes')"
        ) from None
    timeout = NODE_TIMEOUT if args.timeout is None else args.timeout
    return NodeSweep(args.node, family, loaded[0][0], start, args.node_namespace, timeout)


def _record(
    args: argparse.Namespace, space: Any, configurations: list[Any], evaluator: Any
) -> dict[str, object]:
    """The run record: what defines the numbers (a resume must give the same)."""
    from dispeval_ros.offline.bag_eval import bag_location

    return {
        "command": "tune",
        "space": space.record(),
        "samples": args.samples,
        "seed": args.seed if args.samples is not None else None,
        "chunk": 1 if args.node else args.chunk,
        **({"node": args.node} if args.node else {}),
        "scenes": [bag_location(folder) for folder in args.scene],
        "criteria": list(evaluator.criteria),
        "measures": list(evaluator.measures),
        "missing": evaluator.missing,
        "delta": evaluator.delta,
        "mu": evaluator.mu,
        "depth_ranges": args.depth_ranges,
        "configurations": {c.name: c.values for c in configurations},
        **({"fidelity": args.fidelity, "keep": _keep(args)} if args.fidelity is not None else {}),
    }


def _keep(args: argparse.Namespace) -> float:
    return DEFAULT_KEEP if args.keep is None else args.keep


def run(args: argparse.Namespace) -> int:
    """Check everything, sweep, rank, write the table and the parameters files, print."""
    from dispeval_ros.core.objectives import default_objective_measures
    from dispeval_ros.core.provenance import provenance_record
    from dispeval_ros.io import list_frames, scene_folders
    from dispeval_ros.io.jsonio import write_json
    from dispeval_ros.io.provenance import files_sha256
    from dispeval_ros.io.store import SUMMARY_JSON, ResultsStore
    from dispeval_ros.offline.records import write_run_files
    from dispeval_ros.offline.tuning.fidelity import RoundView, round_stamps, run_fidelity
    from dispeval_ros.offline.tuning.outputs import stored_sweep, write_params_files, write_table
    from dispeval_ros.offline.tuning.space import read_space
    from dispeval_ros.offline.tuning.sweep import SweepReport, check_fits, load_scene, run_sweep

    _check_numbers(args)
    space = read_space(args.space)
    configurations = space.configurations(args.samples, args.seed)
    args.scene = list(dict.fromkeys(f for given in args.scene for f in scene_folders(given)))
    listed = [list_frames(folder) for folder in args.scene]
    for frames in listed:  # scored as eval --scene scores them
        common.scene_defaults(args, frames[0].layout)
    evaluator = common.evaluator_from_args(args)
    wanted = args.objective_measures or default_objective_measures(evaluator.measures)
    unknown = [m for m in wanted if m not in evaluator.measures]
    if unknown:
        raise ConfigurationError(
            f"--objective-measures {' '.join(unknown)}: not among the measures scored "
            f"({', '.join(evaluator.measures)})"
        )
    loaded = {i: load_scene(f, evaluator, listed[i]) for i, f in enumerate(args.scene)}
    check_fits(configurations, args.scene, loaded)
    if args.fidelity is not None:  # too few frames: refused before anything is written
        round_stamps([len(loaded[i]) for i in range(len(args.scene))], args.fidelity)
    record = _record(args, space, configurations, evaluator)
    inputs = [path for frames in loaded.values() for frame in frames for path in frame.files]
    progress = Progress("dispeval tune", enabled=not args.quiet, unit="units")

    def update(done: int, total: int, report: SweepReport) -> None:
        progress.update(done, total, report.frames)

    engine = {"chunk": args.chunk, "jobs": args.jobs, "scheduler": args.scheduler}
    fidelity = None
    node: Any = contextlib.nullcontext()
    if args.node:
        node = _connect(args, space.family, loaded, configurations[0])
    with node as sweep, ResultsStore.create(args.out, record, resume=args.resume) as store:
        source: ResultsStore | RoundView = store
        if sweep is not None:
            from dispeval_ros.ros.tune_node import run_node_sweep

            report = run_node_sweep(
                sweep, store, args.scene, loaded, configurations, evaluator, progress=update
            )
        elif args.fidelity is None:
            report = run_sweep(
                store, args.scene, loaded, configurations, evaluator, **engine, progress=update
            )
        else:
            fidelity = run_fidelity(
                store,
                args.scene,
                loaded,
                configurations,
                evaluator,
                args.fidelity,
                _keep(args),
                measures=args.objective_measures,
                granularity=args.objectives,
                **engine,
                progress=update,
            )
            report, source = fidelity.sweep_report(), fidelity.view
        provenance = provenance_record(record, {"files": files_sha256(inputs)})
        store.set_provenance(provenance)
        files = write_run_files(
            source, args.out, provenance, args.objective_measures, args.objectives
        )
        if fidelity is not None:
            write_json(args.out / SUMMARY_JSON, {**files.document, "fidelity": fidelity.to_dict()})
        result = stored_sweep(source, args.objective_measures, args.objectives)
    assert result is not None  # a tune database: its record holds the configurations
    rows, models, objectives = result.rows, result.models, result.objectives
    table_file = write_table(args.out, rows)
    params = write_params_files(args.out, space.family, rows, args.node_name)
    figures, no_figures = _figures(args.out, rows)
    if args.json:
        print_json(
            {
                "results": str(args.out),
                "configurations": {c.name: c.values for c in configurations},
                "objectives": objectives,
                "models": models.to_dict(),
                "params_files": [str(p) for p in params],
                "figures": [str(p) for p in figures],
                "units": {"done": report.units_done, "skipped": report.units_skipped},
                "dropped": report.dropped,
                **({"fidelity": fidelity.to_dict()} if fidelity is not None else {}),
            }
        )
        return 0
    print(_text(args, space, rows, objectives, models, report))
    if fidelity is not None:
        print("\n" + _fidelity_text(fidelity))
    print(f"\ntable: {table_file}")
    folder = params[0].parent if params else args.out
    print(
        wrapped(
            f"parameters files for node {args.node_name}, one per A* group 1 configuration: "
            f"{folder}/NAME.yaml ({plural(len(params), 'file')})"
        )
    )
    if figures:
        print(
            wrapped(
                f"figures: {figures[0].parent}/ (the sweep in parallel coordinates, and each "
                "measure's sensitivity to each swept parameter)"
            )
        )
    else:
        print(f"figures: not drawn ({no_figures})")
    return 0


def _figures(folder: Path, rows: list[Any]) -> tuple[list[Path], str]:
    """The sweep's figures in ``folder/figures`` (none, and why, without matplotlib)."""
    from dispeval_ros.offline.tuning.outputs import FIGURES_FOLDER
    from dispeval_ros.report.sweep import SweepPoint, write_sweep_figures

    points = [
        SweepPoint(r.configuration.name, r.configuration.values, r.measures, r.group) for r in rows
    ]
    try:
        return write_sweep_figures(points, folder / FIGURES_FOLDER), ""
    except ConfigurationError as error:  # matplotlib is an extra
        return [], str(error)


def _text(
    args: argparse.Namespace,
    space: Any,
    rows: list[Any],
    objectives: list[str],
    models: Any,
    report: Any,
) -> str:
    """The sweep's summary line, the best configurations with their values, the reading."""
    from dispeval_ros.testbed.node_parameters import PARAMETERS

    swept = [name for name, values in space.axes.items() if len(values) > 1]
    tags = [PARAMETERS[name].short for name in swept]
    header = ["method", "A* group", "reduced", *tags, *rows[0].measures, "avg rank"]
    body = [
        [
            row.configuration.name,
            row.group,
            "yes" if row.reduced else "",
            *(row.configuration.values[name] for name in swept),
            *row.measures.values(),
            row.rank,
        ]
        for row in rows[:SHOWN_ROWS]
    ]
    scenes = plural(len(args.scene), "scene")
    lines = [
        wrapped(
            f"tune: {plural(len(rows), 'configuration')} of {space.family} on {scenes}; this run: "
            f"{plural(report.units_done, 'unit')} ({report.frames} method-frames)"
            + (f", {report.units_skipped} done before" if report.units_skipped else "")
            + (f"; node {args.node}: {report.dropped} frame(s) dropped" if args.node else "")
        ),
        wrapped(
            f"A* Groups over {plural(len(objectives), 'objective')}, all minimised; measures "
            "shown over all scenes"
            + (f"; best {SHOWN_ROWS} of {len(rows)} shown" if len(rows) > SHOWN_ROWS else "")
            + "; "
            + ", ".join(f"{tag} = {name}" for tag, name in zip(tags, swept, strict=True))
        ),
        table(header, body),
        "",
        wrapped(models.interpretation),
    ]
    return "\n".join(lines)


def _fidelity_text(fidelity: Any) -> str:
    """The rounds: frames, configurations scored and kept, compute against a full sweep's."""
    header = ["round", "frames", "scored", "kept", "config-frames", "seconds"]
    body = [
        [r.round, r.frames, r.configurations, r.kept, r.configuration_frames, f"{r.seconds:.1f}"]
        for r in fidelity.rounds
    ]
    full = fidelity.full_seconds()
    seconds = sum(r.seconds for r in fidelity.rounds)
    estimate = (
        f"; {seconds:.1f} s measured in this run against ≈ {full:.1f} s for the full sweep at "
        "this run's rate"
        if full is not None
        else ""
    )
    first = fidelity.rounds[0]
    return "\n".join(
        [
            wrapped(
                f"multi-fidelity: {plural(first.configurations, 'configuration')} in "
                f"{len(fidelity.rounds)} rounds, whole A* groups kept; the models above are those "
                f"of the {len(fidelity.kept)} of the last round, on every frame"
            ),
            table(header, body),
            wrapped(
                f"compute: {fidelity.configuration_frames} configuration-frames of the full "
                f"sweep's {fidelity.full_configuration_frames} ({fidelity.fraction:.1%})" + estimate
            ),
        ]
    )
