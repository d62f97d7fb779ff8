"""Live pairs: the score statuses carry each frame's pair, and the summarizer pools them as
``dispeval bag --temporal`` does (the sample bag replayed at its log times)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from sample_feed import sample_bag, sample_config, topic_args

from dispeval_ros.cli.main import main
from dispeval_ros.core.egomotion import BASE_COLUMNS, TemporalSums
from dispeval_ros.core.kernels.temporal import PAIR_COUNT
from dispeval_ros.core.temporal import PRESETS, PairScores
from dispeval_ros.errors import InputError
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.stream.core import FrameResult
from dispeval_ros.stream.runner import LiveEvaluator
from dispeval_ros.stream.summarizer import SummarizerConfig, SummarizerCore
from dispeval_ros.stream.vectors import (
    MOTION_SUMS_KEY,
    PAIR_PREFIX,
    PAIR_SUMS_KEY,
    motion_from_status,
    motion_values,
    pair_from_status,
    pair_values,
    result_statuses,
    scores_from_status,
)


@pytest.mark.parametrize("workers", [1, 3])
def test_statuses_carry_the_pairs_and_the_summarizer_pools_those_of_dispeval_bag(
    tmp_path: Path, workers: int
) -> None:
    """With frames scored side by side too: they reach the pair stage in the join's order."""
    bag = sample_bag()
    config = dataclasses.replace(sample_config(bag), temporal="dispeval")
    results: list[FrameResult] = []
    live = LiveEvaluator(config, results.append, queue_size=100_000, workers=workers)
    with BagSource(bag) as source:
        for topic, log_ns, msg in source.messages(list(config.topics)):
            live.push(topic, msg, received=log_ns)
    live.stop(flush=True)
    assert [r.stamp for r in results] == sorted(r.stamp for r in results)
    assert not [text for r in results for _, text in r.problems if "no pair" in text]
    core = SummarizerCore(SummarizerConfig(tmp_path / "live", every_n=3), {"run": "live"})
    carried = 0
    for result in results:
        scores, pairs = {}, {}
        for status in result_statuses(result, config.methods):
            scores[status.name] = scores_from_status(status.values)
            pair = pair_from_status(status.values)
            assert (pair is None) == (status.name not in result.pairs)
            if pair is not None:
                previous, pair_scores = pair
                assert previous == result.pair_previous
                assert np.array_equal(pair_scores.sums, result.pairs[status.name].sums)
                table = dict(status.values)
                assert float(table[f"{PAIR_PREFIX}all/tepe"]) == pair_scores["all"]["tepe"]
                pairs[status.name] = pair
                carried += 1
        core.add(result.stamp, scores, None, pairs)
    core.finish()
    assert carried > 0
    out = tmp_path / "bag"
    assert (
        main(["bag", str(bag), *topic_args(config), "--temporal", "--out", str(out), "--quiet"])
        == 0
    )
    with ResultsStore.open(tmp_path / "live") as store:
        live_pairs = store.pairs(store.sequences()[0])
    with ResultsStore.open(out) as store:
        bag_pairs = store.pairs(store.sequences()[0])
    assert live_pairs is not None
    assert bag_pairs is not None
    assert list(live_pairs) == list(bag_pairs) == list(config.methods)
    for method, pooled in bag_pairs.items():
        assert live_pairs[method].pairs == pooled.pairs > 0
        assert np.array_equal(live_pairs[method].sums, pooled.sums)
        assert live_pairs[method]["all"]["tepe"] == pytest.approx(pooled["all"]["tepe"], rel=0)


def test_a_status_whose_pair_or_residual_keys_do_not_fit_is_one_line() -> None:
    rng = np.random.default_rng(0)
    preset = PRESETS["dispeval"]
    thresholds = np.array([1.0, 0.5, 2.0, 4.0, np.inf, np.inf])[: PAIR_COUNT - 5]
    sums = rng.integers(1, 1000, (1, PAIR_COUNT)).astype(np.float64)
    pair = PairScores(("all",), preset.measures, sums, thresholds, "interpolate", preset)
    width = len(BASE_COLUMNS) + 2
    moved = TemporalSums("egomotion", ("all",), (0.5, 2.0), rng.random((1, width)), (0.1,))
    values = [*pair_values(5, pair), *motion_values(5, moved, with_previous=False)]
    previous, back = pair_from_status(values) or (None, None)
    assert previous == 5
    assert back is not None
    assert np.array_equal(back.sums, pair.sums)
    assert motion_from_status(values) is not None
    for cut, what in [(PAIR_SUMS_KEY, "temporal pair"), (MOTION_SUMS_KEY, "ego-motion")]:
        damaged = [(k, " ".join(v.split()[1:]) if k.endswith(cut) else v) for k, v in values]
        read = pair_from_status if what == "temporal pair" else motion_from_status
        with pytest.raises(InputError, match=f"malformed {what} keys"):
            read(damaged)
        no_criteria = [(k, v) for k, v in values if not k.endswith(cut)]
        with pytest.raises(InputError, match=f"malformed {what} keys"):
            read(no_criteria)
