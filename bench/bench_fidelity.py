"""``tune --fidelity`` against the full sweep, over seeds: was the full first group kept?

For each seed, ``--samples N --seed S`` configurations of config/tune_bm.yaml are swept twice on the
test-bed's synthetic drive (``dispeval make-scene``, written once): in full and with
``--fidelity R --keep F``. Prints per seed whether every member of the full sweep's A* group 1
was kept, whether the final group 1 equals the full one restricted to the kept configurations,
and the compute spent (configuration-frames and measured seconds, as ratios to the full sweep
of the same run). Nothing is asserted about time. The process is pinned to one core:

    python bench/bench_fidelity.py [--seeds 10] [--samples 200] [--fidelity 3] [--keep 0.5]
"""

from __future__ import annotations

import argparse
import io
import json
import tempfile
import time
from contextlib import redirect_stdout
from pathlib import Path

from bench_scoring import pin_to_one_core

from dispeval_ros.cli.main import main as dispeval

SPACE = Path(__file__).resolve().parents[1] / "config" / "tune_bm.yaml"
"""The space swept (1 350 BM configurations; each seed samples --samples of them)."""


def run(argv: list[str]) -> tuple[dict, float]:
    """``dispeval tune ARGV --json --quiet``: its document and wall seconds."""
    buffer = io.StringIO()
    started = time.perf_counter()
    with redirect_stdout(buffer):
        code = dispeval(["tune", *argv, "--json", "--quiet"])
    seconds = time.perf_counter() - started
    if code != 0:
        raise SystemExit(f"dispeval tune {' '.join(argv)} exited {code}")
    return json.loads(buffer.getvalue()), seconds


def first_group(doc: dict) -> set[str]:
    """The names in A* group 1 of a tune document."""
    return {name for name, group in doc["models"]["groups"].items() if group == 1}


def main() -> None:
    """Sweep each seed in full and with --fidelity; print the comparison."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="seeds 0..N−1 (default 10)")
    parser.add_argument("--samples", type=int, default=200, help="configurations (default 200)")
    parser.add_argument("--fidelity", type=int, default=3, help="rounds (default 3)")
    parser.add_argument("--keep", type=float, default=0.5, help="kept fraction (default 0.5)")
    parser.add_argument(
        "--tune-options",
        default="--criteria all",
        help="options given to both sweeps (default '--criteria all': 2 objectives, sze and bmpre on all)",
    )
    parser.add_argument(
        "--scene",
        type=Path,
        action="append",
        help="sweep these scene folders instead of the synthetic drive (repeat)",
    )
    parser.add_argument("--frames", type=int, default=8, help="synthetic frames (default 8)")
    parser.add_argument("--width", type=int, default=320, help="image width (default 320)")
    parser.add_argument("--height", type=int, default=120, help="image height (default 120)")
    args = parser.parse_args()
    pin_to_one_core()
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        if args.scene:
            scenes = [str(s) for s in args.scene]
            data = f"{len(scenes)} scenes ({', '.join(s.name for s in args.scene)})"
        else:
            size = ["--width", str(args.width), "--height", str(args.height)]
            drive = ["make-scene", str(root / "drive"), "--frames", str(args.frames), *size]
            with redirect_stdout(io.StringIO()):
                assert dispeval(drive) == 0
            scenes = [str(next((root / "drive").glob("*/*_sync")))]
            data = f"the synthetic drive, {args.frames} frames of {args.width}×{args.height}"
        common = ["--space", str(SPACE), *args.tune_options.split()]
        common += [a for scene in scenes for a in ("--scene", scene)]
        held = equal = 0
        fractions, ratios = [], []
        print(
            f"{args.samples} BM configurations on {data}, "
            f"--fidelity {args.fidelity} --keep {args.keep} {args.tune_options}"
        )
        print(
            "seed  group 1  kept  all of group 1 kept  final = full ∩ kept  config-frames  seconds"
        )
        for seed in range(args.seeds):
            sample = [*common, "--samples", str(args.samples), "--seed", str(seed)]
            full, full_seconds = run([*sample, "--out", str(root / f"full{seed}")])
            multi, multi_seconds = run(
                [
                    *sample,
                    "--out",
                    str(root / f"multi{seed}"),
                    "--fidelity",
                    str(args.fidelity),
                    "--keep",
                    str(args.keep),
                ]
            )
            kept = set(multi["fidelity"]["kept"])
            group = first_group(full)
            all_kept = group <= kept
            same = first_group(multi) == group & kept
            held += all_kept
            equal += same
            fraction = multi["fidelity"]["compute_fraction"]
            fractions.append(fraction)
            ratios.append(multi_seconds / full_seconds)
            print(
                f"{seed:4d}  {len(group):7d}  {len(kept):4d}  {'yes' if all_kept else 'NO':>19}  "
                f"{'yes' if same else 'NO':>19}  {fraction:13.1%}  {ratios[-1]:6.2f}×"
            )
        print(
            f"all of group 1 kept in {held} of {args.seeds} seeds; final group 1 = full ∩ kept in "
            f"{equal} of {args.seeds}; compute {min(fractions):.1%}–{max(fractions):.1%} of the "
            f"full sweep's configuration-frames (mean {sum(fractions) / len(fractions):.1%}); "
            f"whole command {min(ratios):.2f}–{max(ratios):.2f}× the full sweep's seconds"
        )


if __name__ == "__main__":
    main()
