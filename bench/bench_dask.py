"""``dispeval bag`` on a Dask cluster vs the process pool, and how it would scale.

    python bench/bench_dask.py [--bags 8] [--frames 30] [--width 384] [--height 128] [--rounds 2] [--root DIR]

Writes ``--bags`` synthetic drives, then in the same run (rounds alternate, best of each):

- ``--jobs 2`` (process pool) vs a local Dask cluster of 2 worker processes started before
  (as a real cluster is): the engine's overhead, in %;
- the cost of one unit on a worker and the driver's cost per unit (writing its rows, plus the
  Dask round trip of a task with a unit's payload); throughput with W workers is then at most
  ``min(W / unit_cost, 1 / driver_cost)``, so the driver saturates at ``unit_cost /
  driver_cost`` workers. Machines with fewer cores than that are simulated by this model.

Prints numbers and ratios; asserts nothing (machines are noisy).
"""

from __future__ import annotations

import argparse
import logging
import multiprocessing
import shutil
import tempfile
import time
from multiprocessing.connection import Connection
from pathlib import Path

from scaling import print_scaling, round_trip_cost  # this folder is on sys.path as a script

from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.bag_eval import evaluate_bags, sequence_names
from dispeval_ros.offline.dask_executor import DaskExecutor
from dispeval_ros.offline.make_bag import (
    bag_config,
    synthetic_frames,
    write_bag,
)
from dispeval_ros.offline.units import close_bags, plan_bag, run_unit
from dispeval_ros.stream.core import CoreConfig
from dispeval_ros.testbed import default_methods

METHODS = ("bm_fast", "sgbm")
SLICE_NS = 1_000_000_000


def timed_run(bags: list[Path], config: CoreConfig, out: Path, **engine: object) -> float:
    shutil.rmtree(out, ignore_errors=True)
    started = time.perf_counter()
    with ResultsStore.create(out, {}) as store:
        evaluate_bags(bags, config, store, slice_ns=SLICE_NS, **engine)  # type: ignore[arg-type]
    return time.perf_counter() - started


def pool_runner(connection: Connection) -> None:
    """Time ``--jobs 2`` runs in a process without threads, as the command line runs them.

    (The bench process runs Dask's threads; a pool started from it would spawn its workers.)
    Requests are (bags, config, out, jobs); a first run with jobs=1 compiles the kernels in
    this process, so the pools' forked workers start warm, as a running Dask cluster is.
    """
    while True:
        request = connection.recv()
        if request is None:
            return
        *where, jobs = request
        connection.send(timed_run(*where, jobs=jobs))


def main() -> None:
    """Write the bags, time both engines, then model the scaling."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bags", type=int, default=8)
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--width", type=int, default=384)
    parser.add_argument("--height", type=int, default=128)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--root", type=Path, help="reuse the bags of an earlier run")
    args = parser.parse_args()
    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    root = args.root or Path(tempfile.mkdtemp(prefix="dispeval-bench-dask-"))
    methods = [m for m in default_methods(args.width) if m.name in METHODS]
    started = time.perf_counter()
    bags = []
    for index in range(args.bags):
        bag = root / f"drive{index:02d}"
        if not bag.exists():
            frames = synthetic_frames(args.frames, args.width, args.height, 10.0, seed=index)
            write_bag(bag, frames, storage="rosbag2-mcap", methods=methods)
        bags.append(bag)
    print(
        f"{args.bags} bags of {args.frames} frames, {args.width}×{args.height}, "
        f"{len(METHODS)} methods, written in {time.perf_counter() - started:.1f} s: {root}"
    )
    config = bag_config(METHODS)
    runner_end, bench_end = multiprocessing.get_context("fork").Pipe()
    runner = multiprocessing.get_context("fork").Process(target=pool_runner, args=(runner_end,))
    runner.start()  # before any thread exists, so that its pools fork as the CLI's do
    bench_end.send((bags[:2], config, root / "warm-up-pool", 1))
    bench_end.recv()
    import distributed

    started = time.perf_counter()
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, dashboard_address=None, silence_logs=logging.CRITICAL
    )
    print(f"local Dask cluster of 2 workers started in {time.perf_counter() - started:.1f} s")
    timed_run(bags, config, root / "warm-up", jobs=1)  # compile (or load) the kernels here
    timed_run(bags[:2], config, root / "warm-up", scheduler=cluster.scheduler_address)
    pool, dask = [], []
    for _ in range(args.rounds):
        bench_end.send((bags, config, root / "pool", 2))
        pool.append(bench_end.recv())
        dask.append(timed_run(bags, config, root / "dask", scheduler=cluster.scheduler_address))
    bench_end.send(None)
    runner.join()
    best_pool, best_dask = min(pool), min(dask)
    units = sum(
        len(plan_bag(bag, name, config, SLICE_NS).units)
        for bag, name in zip(bags, sequence_names(bags), strict=True)
    )
    print(f"\n{units} units ({SLICE_NS / 1e9:g} s each) over {args.bags} bags")
    print(f"--jobs 2:                 {best_pool:6.2f} s  (best of {args.rounds})")
    print(
        f"Dask, 2 local workers:    {best_dask:6.2f} s  → engine overhead "
        f"{100 * (best_dask / best_pool - 1):+.1f} % (target ≤ 10 %)"
    )

    # -- the model: cost of a unit on a worker, cost of a unit at the driver ------------------
    plans = [
        plan_bag(bag, name, config, SLICE_NS)
        for bag, name in zip(bags, sequence_names(bags), strict=True)
    ]
    all_units = [unit for plan in plans for unit in plan.units]
    started = time.perf_counter()
    outcomes = [run_unit(config, unit) for unit in all_units]
    unit_cost = (time.perf_counter() - started) / len(all_units)
    close_bags()
    out = root / "driver"
    shutil.rmtree(out, ignore_errors=True)
    with ResultsStore.create(out, {}) as store:
        started = time.perf_counter()
        for outcome in outcomes:
            store.add_prepared(outcome.rows)  # type: ignore[union-attr]
        write_cost = (time.perf_counter() - started) / len(outcomes)
    executor = DaskExecutor(config, cluster.scheduler_address)
    engine_cost, kilobytes = round_trip_cost(executor.client, outcomes)
    executor.close()
    cluster.close()
    driver_cost = write_cost + engine_cost
    print(
        f"\nper unit: {1e3 * unit_cost:.1f} ms on a worker (read, join, score, make rows); "
        f"at the driver {1e3 * driver_cost:.2f} ms ({1e3 * write_cost:.2f} ms writing its rows, "
        f"{1e3 * engine_cost:.2f} ms Dask round trip of its {kilobytes:.0f} kB)"
    )
    print_scaling(unit_cost, driver_cost)
    measured = units / best_dask
    print(
        f"measured with 2 local workers: {measured:.1f} units/s "
        f"(model {min(2 / unit_cost, 1 / driver_cost):.1f}; this machine's cores are shared)"
    )


if __name__ == "__main__":
    main()
