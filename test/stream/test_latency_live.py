"""Live latency: each estimate's delay is its receipt time minus its header stamp."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from sample_feed import sample_bag, sample_config

from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import GT_TOPIC
from dispeval_ros.stream.core import CoreConfig, FrameResult
from dispeval_ros.stream.runner import LiveEvaluator
from dispeval_ros.stream.summarizer import SummarizerConfig, SummarizerCore
from dispeval_ros.stream.vectors import (
    DELAY_ALARM,
    DELAY_KEY,
    ERROR,
    OK,
    WARN,
    AlarmThresholds,
    arrival_of,
    scores_from_status,
    scores_status,
)


@pytest.fixture(scope="module")
def feed() -> tuple[CoreConfig, list[list[tuple[str, Any]]]]:
    """The sample bag's first three frames, each as its messages (GT first)."""
    bag: Path = sample_bag()
    config = sample_config(bag)
    with BagSource(bag) as source:
        messages = [(topic, msg) for topic, _, msg in source.messages(list(config.topics))]
    stamps = sorted({stamp_ns(msg.header) for topic, msg in messages if topic == GT_TOPIC})
    frames = [
        sorted(
            ((t, m) for t, m in messages if stamp_ns(m.header) == stamp),
            key=lambda item: item[0] != GT_TOPIC,
        )
        for stamp in stamps[:3]
    ]
    return config, frames


def late_by(config: CoreConfig, topic: str, index: int) -> int:
    """A receipt delay (ns) that differs by method and frame."""
    methods = list(config.methods.values())
    if topic not in methods:
        return 1_000_000
    return 7_000_000 + 11_000_000 * methods.index(topic) + 3_000_000 * index


def received_live(
    config: CoreConfig, frames: list[list[tuple[str, Any]]]
) -> tuple[list[FrameResult], dict[tuple[int, str], int]]:
    """The results of pushing ``frames`` with receipt times (:func:`late_by`), and those times
    by (estimate stamp, method)."""
    results: list[FrameResult] = []
    live = LiveEvaluator(config, results.append, queue_size=100)
    received: dict[tuple[int, str], int] = {}
    method_of = {topic: name for name, topic in config.methods.items()}
    for index, frame in enumerate(frames):
        for topic, msg in frame:
            when = stamp_ns(msg.header) + late_by(config, topic, index)
            if topic in method_of:
                received[stamp_ns(msg.header), method_of[topic]] = when
            live.push(topic, msg, received=when)
    live.stop(flush=True)
    return results, received


def test_delays_are_the_receipt_times_given_minus_the_stamps(
    feed: tuple[CoreConfig, list[list[tuple[str, Any]]]],
) -> None:
    config, frames = feed
    results, received = received_live(config, frames)
    assert {r.stamp for r in results} == {stamp for stamp, _ in received}
    seen = {}
    for result in results:
        assert set(result.arrivals) == set(config.methods)
        for method, delay in result.delays().items():
            assert result.arrivals[method] == received[result.sent[method], method]
            seen[result.stamp, method] = delay
    assert seen == {(stamp, method): when - stamp for (stamp, method), when in received.items()}
    assert len(set(seen.values())) > 1


def test_without_receipt_times_the_clock_shifted_by_the_epoch_is_the_receipt(
    feed: tuple[CoreConfig, list[list[tuple[str, Any]]]],
) -> None:
    config, frames = feed
    first = stamp_ns(frames[0][0][1].header)
    now = [0.0]
    results: list[FrameResult] = []
    live = LiveEvaluator(config, results.append, clock=lambda: now[0], epoch=first / 1e9)
    expected = {}
    for index, frame in enumerate(frames):
        for topic, msg in frame:
            stamp = stamp_ns(msg.header)
            now[0] = (stamp - first + late_by(config, topic, index)) / 1e9
            live.push(topic, msg)
            if topic in config.methods.values():
                expected[stamp, topic] = round((now[0] + first / 1e9) * 1e9) - stamp
    live.stop(flush=True)
    assert results
    for result in results:
        for method, delay in result.delays().items():
            assert delay == expected[result.sent[method], config.methods[method]]
            assert abs(delay - late_by(config, config.methods[method], 0)) < 10_000_000


def test_the_scores_statuses_carry_the_latency_to_the_summarizer_database(
    feed: tuple[CoreConfig, list[list[tuple[str, Any]]]], tmp_path: Path
) -> None:
    """Evaluator → ``/dispeval/scores`` statuses → summarizer: the delays stored are the
    receipt times minus the stamps, as ``dispeval bag`` stores log time minus stamp."""
    config, frames = feed
    results, received = received_live(config, frames)
    core = SummarizerCore(SummarizerConfig(tmp_path / "out", every_n=2), {"run": "live"})
    for result in sorted(results, key=lambda r: r.stamp):
        scores, arrivals = {}, {}
        for method, method_scores in result.scores.items():
            status = scores_status(
                method,
                config.methods[method],
                method_scores,
                estimate_stamp=result.estimate_stamps[method],
                arrival=result.arrivals[method],
            )
            table = dict(status.values)
            delay = result.arrivals[method] - result.estimate_stamps[method]
            assert float(table[DELAY_KEY]) == delay / 1e6
            scores[method] = scores_from_status(status.values)
            found = arrival_of(status.values)
            assert found is not None
            arrivals[method] = found
        core.add(result.stamp, scores, arrivals)
    summary = core.finish()
    assert summary is not None
    with ResultsStore.open(tmp_path / "out") as store:
        timing = store.timing(store.sequences()[0])
    assert timing is not None
    stored = {(e.stamp, e.method): e.delay for entries in timing.values() for e in entries}
    assert stored == {key: when - key[0] for key, when in received.items()}
    assert summary.sequences[0].timing is not None


def test_the_latency_alarm_sets_the_status_level(
    feed: tuple[CoreConfig, list[list[tuple[str, Any]]]],
) -> None:
    config, frames = feed
    results, _ = received_live(config, frames[:1])
    (result,) = results
    alarms = AlarmThresholds.parse([f"{DELAY_ALARM}=10"], [f"{DELAY_ALARM}=20"])
    levels = {}
    for method, scores in result.scores.items():
        status = scores_status(
            method, "", scores, alarms, result.estimate_stamps[method], result.arrivals[method]
        )
        levels[result.delays()[method] / 1e6] = status.level
    assert levels == {
        delay: ERROR if delay > 20 else WARN if delay > 10 else OK for delay in levels
    }
    assert len(set(levels.values())) > 1
