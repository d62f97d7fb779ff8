"""Pareto models at sweep scale against ``moocore.pareto_rank``, measured in the same run.

Prints timings and ratios only (nothing is asserted about time), and checks that the A* Groups
are identical to moocore's fronts. Run (``moocore`` comes with the ``test`` extra):

    python bench/bench_models.py [--methods N] [--repeat R]

Inputs mimic a parameter sweep: every method has a latent quality and each objective is that
quality plus noise, rounded to whole numbers (as tables print them): correlated objectives with many
ties and duplicate rows. M = 2, 12 and 50 objectives. Then the large fronts of sweeps whose
measures barely agree: uniform random objectives (M = 4, 8, 12) and a weakly correlated case
(latent quality plus noise twice its spread). Last, the front reduction of a front of about
7 000 methods (two anti-correlated objective groups). The process is pinned to one core.
"""

from __future__ import annotations

import argparse

import numpy as np
from bench_scoring import pin_to_one_core, timed

from dispeval_ros.core.models import astar_groups, front_reduction, pareto_front


def sweep_objectives(methods: int, objectives: int, seed: int = 0) -> np.ndarray:
    """Correlated objectives with many ties: latent quality + noise, rounded to whole numbers."""
    rng = np.random.default_rng(seed)
    quality = rng.gamma(2.0, 5.0, size=(methods, 1))
    noise = rng.normal(0.0, 0.7, size=(methods, objectives))
    return np.round(quality + noise)


def random_objectives(methods: int, objectives: int, seed: int = 2) -> np.ndarray:
    """Independent uniform objectives: most methods in the first few, huge, fronts."""
    return np.random.default_rng(seed).random((methods, objectives))


def weakly_correlated(methods: int, objectives: int, seed: int = 3) -> np.ndarray:
    """A latent quality plus noise of twice its spread: weakly correlated objectives."""
    rng = np.random.default_rng(seed)
    quality = rng.random((methods, 1))
    return quality + rng.normal(0.0, 2.0 * quality.std(), size=(methods, objectives))


def compare(matrix: np.ndarray, repeat: int) -> None:
    """Time astar_groups and pareto_front against moocore.pareto_rank; check identical fronts."""
    import moocore

    methods, objectives = matrix.shape
    ours = astar_groups(matrix)
    theirs = moocore.pareto_rank(matrix) + 1
    identical = bool(np.array_equal(ours, theirs))
    same_front = bool(np.array_equal(pareto_front(matrix), theirs == 1))
    unique_rows = len(np.unique(matrix, axis=0))
    t_ours = timed(lambda: astar_groups(matrix), repeat)
    t_front = timed(lambda: pareto_front(matrix), repeat)
    t_moocore = timed(lambda: moocore.pareto_rank(matrix), repeat)
    print(
        f"  M = {objectives:2d}: {int(ours.max()):4d} groups, |A*| = {int((ours == 1).sum()):4d},"
        f" {methods - unique_rows} duplicate rows; fronts identical to moocore: "
        f"{identical}, A* identical: {same_front}"
    )
    print(f"    moocore.pareto_rank          {t_moocore:9.2f} ms   1.0×")
    print(f"    astar_groups                 {t_ours:9.2f} ms   {t_moocore / t_ours:6.1f}× faster")
    print(
        f"    pareto_front (A* only)       {t_front:9.2f} ms   {t_moocore / t_front:6.1f}× faster"
    )


def wide_front(methods: int, objectives: int = 12, seed: int = 1) -> np.ndarray:
    """A matrix whose A* holds most methods: two groups of objectives pulling apart."""
    rng = np.random.default_rng(seed)
    trade = rng.random((methods, 1))
    half = objectives // 2
    first = trade + rng.normal(0.0, 0.02, size=(methods, half))
    second = (1.0 - trade) + rng.normal(0.0, 0.02, size=(methods, objectives - half))
    return np.round(np.hstack([first, second]) * 100.0, 1)


def main() -> None:
    """Time A* Groups on correlated (M = 2, 12, 50), random and weakly correlated objectives."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", type=int, default=10_000, help="methods (rows), default 1e4")
    parser.add_argument("--repeat", type=int, default=5, help="timed calls per measurement")
    args = parser.parse_args()
    pin_to_one_core()
    print(f"dispeval_ros models benchmark (one core; median of {args.repeat} calls)")
    print(f"\nA* Groups, N = {args.methods} methods, correlated objectives, rounded")
    for objectives in (2, 12, 50):
        compare(sweep_objectives(args.methods, objectives), args.repeat)
    print(f"\nA* Groups, N = {args.methods} methods, random objectives, uniform")
    for objectives in (4, 8, 12):
        compare(random_objectives(args.methods, objectives), args.repeat)
    print(f"\nA* Groups, N = {args.methods} methods, weakly correlated objectives")
    compare(weakly_correlated(args.methods, 12), args.repeat)
    matrix = wide_front(8000)
    group = matrix[astar_groups(matrix) == 1]
    t_reduction = timed(lambda: front_reduction(group), args.repeat)
    reduced = int(front_reduction(group).reduced.sum())
    print(
        f"\nfront reduction of a {len(group)}-method front × {group.shape[1]} objectives: "
        f"{t_reduction:.2f} ms ({reduced} chosen)"
    )


if __name__ == "__main__":
    main()
