"""``dispeval tune`` on a Dask cluster: how a 1 000-configuration sweep would scale on N workers.

    python bench/bench_tune_dask.py [--configurations 1000] [--chunk 8] [--units 4]

Scene: KITTI 2015 000005_10 (1242×375) from the shared data (``DISPEVAL_DATA`` or
``../shared/data``); configurations: a seeded sample of an SGBM space (windows 5–15,
uniqueness 5–15, the four modes, ``disparity_range`` 128). Measured in this run:

- the cost of one unit on a worker (``--chunk`` configurations: OpenCV maps, scores, rows; the
  mean of ``--units`` units, one OpenCV thread, as each Dask worker runs them);
- the driver's cost per unit: writing its rows into the database, and the Dask round trip of a
  task with its payload (a local cluster of 2 workers);
- a real sweep of the ``--units`` units on that cluster (its address as ``--scheduler``, the
  workers warmed up by a first sweep), against the model's rate for 2 workers.

The model (``scaling.py``, as ``bench_dask.py``'s) then gives units/s, speed-up and the time of
the ``--configurations`` sweep for 1–256 workers: the cores this machine lacks are simulated.
Prints numbers; asserts nothing (machines are noisy).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import statistics
import tempfile
import time
from pathlib import Path

import cv2
from scaling import print_scaling, round_trip_cost  # this folder is on sys.path as a script

from dispeval_ros.core import Evaluator
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.tuning.space import space_from_document
from dispeval_ros.offline.tuning.sweep import Setup, _Worker, evaluator_settings, run_sweep
from dispeval_ros.stream.tuning import load_scene, plan

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(os.environ.get("DISPEVAL_DATA") or ROOT.parent / "shared" / "data")
SPACE = {
    "family": "sgbm",
    "parameters": {
        "correlation_window_size": {"min": 5, "max": 15, "step": 2},
        "uniqueness_ratio": {"min": 5, "max": 15},
        "sgbm_mode": [0, 1, 2, 3],
        "disparity_range": 128,
    },
}


def main() -> None:
    """Measure a unit's cost at the worker and at the driver, a real 2-worker run, the model."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configurations", type=int, default=1000, help="the sweep modelled")
    parser.add_argument("--chunk", type=int, default=8, help="configurations per unit")
    parser.add_argument("--units", type=int, default=4, help="units timed on a worker")
    args = parser.parse_args()
    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    cv2.setNumThreads(1)  # as a Dask worker of one thread runs OpenCV
    scene = DATA / "kitti-2015" / "000005_10"
    if not scene.is_dir():
        raise SystemExit(f"{scene}: not found (set DISPEVAL_DATA to the shared data)")
    space = space_from_document(SPACE, "bench")
    sample = space.configurations(args.units * args.chunk, seed=0)
    evaluator = Evaluator()
    loaded = {0: load_scene(scene, evaluator)}
    setup = Setup((scene.absolute(),), evaluator_settings(evaluator))
    units = plan(["kitti"], sample, args.chunk)
    worker = _Worker(setup, loaded)
    worker.run(units[0])  # warm up: matchers, kernels
    costs, outcomes = [], []
    for unit in units:
        started = time.perf_counter()
        outcomes.append(worker.run(unit))
        costs.append(time.perf_counter() - started)
    unit_cost = statistics.mean(costs)
    with tempfile.TemporaryDirectory() as folder:
        with ResultsStore.create(Path(folder) / "driver", {"bench": "tune"}) as store:
            started = time.perf_counter()
            for outcome in outcomes:
                store.add_prepared(outcome)
            write_cost = (time.perf_counter() - started) / len(outcomes)
        import distributed

        cluster = distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, dashboard_address=None, silence_logs=logging.CRITICAL
        )
        with distributed.Client(cluster) as client:
            engine_cost, kilobytes = round_trip_cost(client, outcomes)
        address = cluster.scheduler_address  # started before, as a real cluster is

        def sweep(name: str, configurations: list) -> float:
            started = time.perf_counter()
            with ResultsStore.create(Path(folder) / name, {"bench": "tune"}) as store:
                run_sweep(store, [scene], loaded, configurations, evaluator,
                          chunk=args.chunk, scheduler=address)  # fmt: skip
            return time.perf_counter() - started

        sweep("warm-up", sample[: 2 * args.chunk])  # each worker loads the scene, compiles
        measured = len(units) / sweep("dask", sample)
        cluster.close()
    driver_cost = write_cost + engine_cost
    print(
        f"{len(sample)} SGBM configurations on KITTI 000005_10, units of {args.chunk}: "
        f"{unit_cost:.2f} s a unit on a worker ({1e3 * unit_cost / args.chunk:.0f} ms a "
        f"configuration); at the driver {1e3 * driver_cost:.2f} ms a unit "
        f"({1e3 * write_cost:.2f} ms writing its rows, {1e3 * engine_cost:.2f} ms Dask round "
        f"trip of its {kilobytes:.0f} kB)"
    )
    print(
        f"measured on a local cluster of 2 workers (started and warmed up before): {measured:.2f} "
        f"units/s (model {min(2 / unit_cost, 1 / driver_cost):.2f}; this machine's 2 cores "
        "are shared)"
    )
    total = math.ceil(args.configurations / args.chunk)
    print(f"\na sweep of {args.configurations} configurations on this scene: {total} units")
    print_scaling(unit_cost, driver_cost, total)


if __name__ == "__main__":
    main()
