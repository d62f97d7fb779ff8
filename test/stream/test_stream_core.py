"""The transport-free live core, fed the sample bag's messages as a robot would deliver them."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from sample_feed import bag_reference, expected_counts, robot_stream, sample_bag, sample_config

from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.encoders import disparity_to_msg, image_to_msg
from dispeval_ros.io.messages import stamp_ns
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import GT_TOPIC
from dispeval_ros.stream.core import CoreConfig, EvaluationCore, FrameResult
from dispeval_ros.stream.images import colour_error
from dispeval_ros.stream.join import FrameSet
from dispeval_ros.stream.replay import replay
from dispeval_ros.stream.runner import LiveEvaluator
from dispeval_ros.stream.summarizer import SummarizerConfig, SummarizerCore, group_statuses
from dispeval_ros.stream.vectors import (
    ERROR,
    OK,
    WARN,
    AlarmThresholds,
    score_vector,
    scores_from_status,
    scores_status,
    vector_labels,
)
from dispeval_ros.summary import summarize


@pytest.fixture(scope="module")
def sample() -> Path:
    return sample_bag()


@pytest.fixture(scope="module")
def reference_run(
    sample: Path, tmp_path_factory: pytest.TempPathFactory
) -> dict[tuple[int, str], Any]:
    return bag_reference(sample, tmp_path_factory.mktemp("bag") / "out")


def test_node_core_matches_dispeval_bag_with_jitter_and_drops(
    sample: Path, reference_run: dict[tuple[int, str], Any]
) -> None:
    config = sample_config(sample)
    stream, expected = robot_stream(sample, config)
    messages = [(topic, msg) for topic, _, msg in stream]
    results: list[FrameResult] = []
    lock = threading.Lock()

    def collect(result: FrameResult) -> None:
        with lock:
            results.append(result)

    live = LiveEvaluator(config, collect, queue_size=1000)
    for topic, msg in messages:
        live.push(topic, msg)
    live.stop(flush=True)

    scored = {(r.stamp, m): s for r in results for m, s in r.scores.items()}
    for key, scores in scored.items():
        np.testing.assert_array_equal(scores.sums, reference_run[key].sums, err_msg=str(key))
    counts = live.counts()
    assert counts == expected_counts(config, expected)
    assert len(scored) == sum(c.matched for c in counts.values())
    assert live.stats.queue_drops == 0


def test_bounded_queue_drops_oldest_and_counts(sample: Path) -> None:
    config = sample_config(sample)
    release = threading.Event()
    seen: list[int] = []

    def slow(result: FrameResult) -> None:
        release.wait(10)
        seen.append(result.stamp)

    live = LiveEvaluator(config, slow, queue_size=2)
    with BagSource(sample) as source:
        for topic, _, msg in source.messages(list(config.topics)):
            live.push(topic, msg)  # never blocks although scoring is stuck
    release.set()
    live.stop(flush=True)
    counts = live.counts()
    assert live.stats.queue_drops > 0
    total = len(seen) + live.stats.queue_drops
    assert all(c.matched + c.dropped == total for c in counts.values())
    assert seen == sorted(seen)


def test_statuses_round_trip_exactly_and_raise_alarms(
    reference_run: dict[tuple[int, str], Any],
) -> None:
    (stamp, method), scores = next(iter(reference_run.items()))
    alarms = AlarmThresholds.parse(["all/bmp=0.0"], ["all/density=1.01"])
    status = scores_status(method, "/topic", scores, alarms, estimate_stamp=stamp)
    assert status.level == ERROR  # density is always below 1.01
    assert status.name == method
    rebuilt = scores_from_status(status.values)
    np.testing.assert_array_equal(rebuilt.sums, scores.sums)
    for criterion in scores.criteria:
        for measure, value in scores[criterion].items():
            assert rebuilt[criterion][measure] == pytest.approx(value, nan_ok=True, rel=0, abs=0)
    assert (
        scores_status(method, "/t", scores, AlarmThresholds.parse(["all/bmp=0"], [])).level == WARN
    )
    assert scores_status(method, "/t", scores).level == OK
    labels = vector_labels(scores.criteria, scores.measures)
    vector = score_vector(scores, labels)
    assert len(vector) == len(labels)
    assert labels[:2] == [f"{scores.criteria[0]}/n", f"{scores.criteria[0]}/density"]
    assert vector[0] == scores[scores.criteria[0]]["n"]


def test_summarizer_writes_the_bag_database_and_groups(
    reference_run: dict[tuple[int, str], Any], tmp_path: Path
) -> None:
    stamps = sorted({stamp for stamp, _ in reference_run})
    methods = sorted({method for _, method in reference_run})
    core = SummarizerCore(SummarizerConfig(tmp_path / "out", every_n=10), {"source": "test"})
    summaries = []
    for stamp in stamps:
        frame = {
            m: scores_from_status(scores_status(m, "/t", reference_run[stamp, m]).values)
            for m in methods
        }
        result = core.add(stamp, frame)
        if result is not None:
            summaries.append(result)
    assert len(summaries) == len(stamps) // 10
    # the live summaries come from running totals: the same models as a summary of the database
    from_database = summarize(core.store)
    live_models = summaries[-1].sequences[0].models
    database_models = from_database.sequences[0].models
    assert live_models is not None
    assert database_models is not None
    assert live_models.groups == database_models.groups
    assert live_models.reduced == database_models.reduced
    for method, terms in database_models.reduction.items():
        assert live_models.reduction[method] == pytest.approx(terms, rel=1e-12)
    assert summaries[-1].sequences[0].common_frames == from_database.sequences[0].common_frames
    final = core.finish()
    assert final is not None
    records = group_statuses(final, core.sequence)
    assert {r.name for r in records} == set(methods)
    assert all(dict(r.values)["interpretation"] for r in records)
    with ResultsStore.open(tmp_path / "out") as store:
        (sequence,) = store.sequences()
        assert store.stamps(sequence) == stamps
        totals = store.sequence_scores(sequence)
    for method in methods:
        expected = np.sum([reference_run[s, method].sums for s in stamps], axis=0)
        np.testing.assert_allclose(totals[method].sums, expected, rtol=1e-12)
    assert (tmp_path / "out" / "summary.json").is_file()
    assert (tmp_path / "out" / "frames.csv").is_file()


def test_error_images_and_replay(sample: Path) -> None:
    config = sample_config(sample)
    results: list[FrameResult] = []
    live = LiveEvaluator(config, results.append, queue_size=100, error_images=True)
    pushed = replay(sample, list(config.topics), live.push, rate=None)
    live.stop(flush=True)
    assert pushed > 0
    result = results[0]
    method = next(iter(result.errors))
    error = result.errors[method]
    assert error.dtype == np.float32
    assert result.partition is not None
    assert np.isnan(error[result.partition.cells < 0]).all()
    rgb = colour_error(error, result.partition)
    assert rgb.dtype == np.uint8
    assert rgb.shape == (*error.shape, 3)


def test_replay_keeps_the_recorded_rate(sample: Path) -> None:
    """At rate 2 the pushes follow the log times at half the spacing (a fake clock, no sleeping)."""
    now = [0.0]
    slept: list[float] = []

    def sleep(seconds: float) -> None:
        slept.append(seconds)
        now[0] += seconds

    pushed: list[str] = []
    count = replay(
        sample,
        [GT_TOPIC],
        lambda t, m, r: pushed.append(t),
        rate=2.0,
        clock=lambda: now[0],
        sleep=sleep,
    )
    assert count == len(pushed) == 25
    assert now[0] == pytest.approx(2.4 / 2.0, rel=1e-6)  # 25 frames at 10 Hz span 2.4 s


def _frame_of_three(broken: str) -> tuple[CoreConfig, FrameSet]:
    """One joined frame of methods a, b, c; ``broken`` is ``method:defect``.

    Defects: ``width`` (scoring fails), ``encoding`` (decoding fails).
    """
    broken_method, _, defect = broken.partition(":")
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    rng = np.random.default_rng(7)
    gt = rng.uniform(5.0, 40.0, (48, 64)).astype(np.float32)
    stamp = 1_700_000_000_000_000_000
    estimates = {}
    for index, method in enumerate("abc"):
        width = 60 if (method, defect) == (broken_method, "width") else 64
        estimate = gt[:, :width] + rng.normal(0.0, 1.0 + index, (48, width)).astype(np.float32)
        estimate[rng.random(estimate.shape) < 0.1] = -1.0  # invalid pixels
        msg = disparity_to_msg(typestore, estimate, stamp, "l", 100.0, 0.5, 0.0, 63.0)
        if (method, defect) == (broken_method, "encoding"):
            msg.image.encoding = "16UC1"
        estimates[method] = (stamp + index, msg)
    config = CoreConfig(methods={m: f"/{m}" for m in "abc"}, gt_topic="/gt")
    gt_msg = image_to_msg(typestore, gt, stamp, "l", "32FC1")
    return config, FrameSet(stamp, gt_msg, estimates)


@pytest.mark.parametrize("broken", ["a:encoding", "a:width", "b:width", "c:encoding", ""])
def test_methods_scored_on_threads_give_the_result_of_one_thread(broken: str) -> None:
    """Scores bit for bit, problems in method order, failed counts: as scored one by one."""
    config, frame_set = _frame_of_three(broken)
    alone = EvaluationCore(config, error_images=True)
    expected = alone.score(frame_set)
    with ThreadPoolExecutor(3) as pool:
        threaded = EvaluationCore(config, error_images=True, executor=pool)
        results = [threaded.score(frame_set) for _ in range(4)]
    for result in results:
        assert list(result.scores) == list(expected.scores)
        for method, scores in expected.scores.items():
            assert result.scores[method].sums.tobytes() == scores.sums.tobytes()
            assert result.errors[method].tobytes() == expected.errors[method].tobytes()
        assert result.estimate_stamps == expected.estimate_stamps
        assert result.problems == expected.problems
    assert {m: n * 4 for m, n in alone.failed.items()} == threaded.failed
    failed = [p[0] for p in expected.problems]
    if broken == "a:encoding":  # the first estimate gives the camera: without it the frame fails
        assert list(expected.scores) == []
        assert failed == [None]
        assert "/a" in expected.problems[0][1]
        assert alone.failed == {"a": 1, "b": 1, "c": 1}
    elif broken:
        method, _, defect = broken.partition(":")
        assert list(expected.scores) == [m for m in "abc" if m != method]
        assert failed == [method]
        assert ("60" if defect == "width" else "16UC1") in expected.problems[0][1]
    else:
        assert list(expected.scores) == ["a", "b", "c"]
        assert expected.problems == []


def test_live_waits_on_the_receipt_clock_whatever_the_stamps(sample: Path) -> None:
    """Live, lateness is receipt time: estimates received 1.2 s after their frame (lateness
    1 s) count unmatched and the frame dropped, although their stamps equal the frame's."""
    config = sample_config(sample)
    with BagSource(sample) as source:
        messages = [(topic, msg) for topic, _, msg in source.messages(list(config.topics))]
    gt_stamps = sorted({stamp_ns(msg.header) for topic, msg in messages if topic == GT_TOPIC})
    frames = [[(t, m) for t, m in messages if stamp_ns(m.header) == s] for s in gt_stamps[:2]]
    now = [0.0]  # seconds of receipt time, decades away from the stamps
    results: list[FrameResult] = []
    live = LiveEvaluator(config, results.append, clock=lambda: now[0])
    for index, frame in enumerate(frames):
        now[0] = 10.0 * index
        for topic, msg in frame:
            if topic in config.methods.values():
                now[0] = 10.0 * index + (0.3 if index == 0 else 1.2)
            live.push(topic, msg)
    live.stop(flush=True)
    assert [result.stamp for result in results] == gt_stamps[:1]
    assert set(results[0].scores) == set(config.methods)
    for method, counts in live.counts().items():
        assert (counts.matched, counts.unmatched, counts.dropped) == (1, 1, 1), method
