"""The ego-motion residual in the pair stage (stream/pairs.py), on a synthetic-drive bag.

The camera's motion is the drive's exact motion, injected through the stage's ``motion``
callable (as the stream's /tf history gives it). The stage scores exactly what
:func:`egomotion_residual` scores on the frames the bag was made of (so the camera, its
principal point and frame from the CameraInfo, the doffs taken off the published values and
the GT-free criteria reach it as they are); the true disparity fits the exact motion, a noisy
one does not, nor does the true disparity under the inverted motion (the convention: the pose
of the camera at t1 in its frame at t0).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bag_support import drive_motion_lookup, noisy_drive_bag

from dispeval_ros.core.egomotion import PinholeCamera, egomotion_residual, prepare_frame
from dispeval_ros.core.gtfree import DEFAULT_GT_FREE_CRITERIA, GroundTruthFree
from dispeval_ros.core.transforms import invert_rigid
from dispeval_ros.errors import InputError
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import (
    CAMERA_FRAME,
    GT_TOPIC,
    LEFT_IMAGE,
    LEFT_INFO,
    RIGHT_IMAGE,
    RIGHT_INFO,
    START_NS,
    disparity_topic,
    synthetic_frames,
)
from dispeval_ros.stream.core import CoreConfig, EvaluationCore, FrameResult
from dispeval_ros.stream.summarizer import SummarizerConfig, SummarizerCore
from dispeval_ros.stream.vectors import (
    MOTION_PREFIX,
    motion_from_status,
    result_statuses,
    scores_from_status,
)

FRAMES = 4


WIDTH, HEIGHT, SEED = 620, 188, 4
NOISE = {"truth": 0.0, "noisy": 0.5}
"""px of Gaussian noise on the GT, drawn anew in each frame."""


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The drive with the true disparity and a noisy one published as methods."""
    root = tmp_path_factory.mktemp("ego")
    drive = list(synthetic_frames(FRAMES, WIDTH, HEIGHT, 10.0, seed=SEED))
    return noisy_drive_bag(root, drive, NOISE, seed=5)


drive_motion = drive_motion_lookup(WIDTH, HEIGHT, SEED)
"""The exact motion of the drive (the pair stage's lookup)."""


def run(bag: Path, motion: Any, temporal: str | None = None) -> list[FrameResult]:
    config = CoreConfig(
        methods={m: disparity_topic(m) for m in NOISE},
        gt_topic=GT_TOPIC,
        left_info_topic=LEFT_INFO,
        right_info_topic=RIGHT_INFO,
        left_image_topic=LEFT_IMAGE,
        right_image_topic=RIGHT_IMAGE,
        egomotion=True,
        temporal=temporal,
    )
    core = EvaluationCore(config)
    assert core.pairs is not None
    core.pairs.motion = motion
    results = []
    with BagSource(bag) as source:
        for topic, log_ns, msg in source.messages(list(config.topics)):
            results += [core.pair(core.score(s)) for s in core.push(topic, msg, log_ns)]
    return results + [core.pair(core.score(s)) for s in core.flush()]


def pooled(results: list[FrameResult], method: str):
    parts = [p.sums for r in results for p in r.motion_pairs if p.method == method]
    total = parts[0]
    for part in parts[1:]:
        total = total + part
    return len(parts), total


def test_the_stage_scores_what_the_residual_scores_on_the_frames_it_was_made_of(
    bag: Path,
) -> None:
    """Camera, principal point, criteria, doffs and motion reach the residual as they are."""
    results = run(bag, drive_motion)
    assert not [p for r in results for p in r.problems if "ego-motion" in p[1]]
    drive = list(synthetic_frames(FRAMES, WIDTH, HEIGHT, 10.0, seed=SEED))
    free = GroundTruthFree(DEFAULT_GT_FREE_CRITERIA)
    scored = [r for r in results if r.motion_pairs]
    assert len(scored) == FRAMES - 1
    for index, result in enumerate(scored, start=1):
        first, second = drive[index - 1], drive[index]
        stamps = (START_NS + round(first.stamp * 1e9), START_NS + round(second.stamp * 1e9))
        assert (result.pair_previous, result.stamp) == stamps
        direct = egomotion_residual(
            prepare_frame(first.gt, first.left),
            prepare_frame(second.gt, second.left),
            drive_motion(CAMERA_FRAME, *stamps),
            PinholeCamera(first.camera, *first.principal),
            free.pair(first.left, first.right).partition,
        )
        [got] = [p.sums for p in result.motion_pairs if p.method == "truth"]
        assert got.criteria == direct.criteria
        assert np.array_equal(got.sums, direct.sums)


def test_the_exact_motion_tells_noise_apart_and_an_inverted_one_does_not_fit(bag: Path) -> None:
    results = run(bag, drive_motion)
    _, truth = pooled(results, "truth")
    _, noisy = pooled(results, "noisy")
    true_all = truth.summary("all")
    assert true_all["n_residual"] > 0.3 * true_all["n"]
    # within 0.5 px but where things move (traffic, the far wall that keeps its distance)
    assert true_all["bad_0.5"] < 10
    assert noisy.summary("all")["bad_0.5"] > 3 * true_all["bad_0.5"]
    _, inverted = pooled(run(bag, lambda c, a, b: invert_rigid(drive_motion(c, a, b))), "truth")
    assert inverted.summary("all")["bad_0.5"] > 3 * true_all["bad_0.5"]


def test_a_motion_that_cannot_be_looked_up_is_one_line_per_pair(bag: Path) -> None:
    def unknown(camera_frame: str, t0_ns: int, t1_ns: int) -> np.ndarray:
        raise InputError(f"no /tf transform received for '{camera_frame}'")

    results = run(bag, unknown, temporal="dispeval")
    lines = [text for r in results for method, text in r.problems if "ego-motion" in text]
    assert len(lines) == FRAMES - 1
    assert all(f"no /tf transform received for '{CAMERA_FRAME}'" in t for t in lines)
    assert not any(r.motion_pairs for r in results)
    assert sum(len(r.pairs) for r in results) == len(NOISE) * (
        FRAMES - 1
    )  # tepe is scored regardless


def test_statuses_carry_the_residual_and_the_summarizer_stores_it(
    bag: Path, tmp_path: Path
) -> None:
    results = run(bag, drive_motion)
    config = {m: disparity_topic(m) for m in NOISE}
    core = SummarizerCore(SummarizerConfig(tmp_path / "live", every_n=2), {"run": "live"})
    for result in results:
        scores, motion = {}, {}
        for status in result_statuses(result, config):
            scores[status.name] = scores_from_status(status.values)
            found = motion_from_status(status.values)
            mine = {p.method: p for p in result.motion_pairs if p.stamp == result.stamp}
            assert (found is None) == (status.name not in mine)
            if found is not None:
                previous, sums = found
                assert previous == result.pair_previous
                assert np.array_equal(sums.sums, mine[status.name].sums.sums)
                value = dict(status.values)[f"{MOTION_PREFIX}gtfree:all/mean_abs"]
                assert float(value) == sums.summary("all")["mean_abs"]
                motion[status.name] = found
        core.add(result.stamp, scores, None, None, motion)
    summary = core.finish()
    assert summary is not None
    assert summary.egomotion
    with ResultsStore.open(tmp_path / "live") as store:
        stored = store.motion_pairs(store.sequences()[0])
    assert stored is not None
    for method in NOISE:
        pairs, pooled_sums = pooled(results, method)
        assert stored[method][0] == pairs
        assert np.array_equal(stored[method][1].sums, pooled_sums.sums)
    entry = summary.to_dict()["sequences"][0]["egomotion"]["truth"]
    assert entry["pairs"] == FRAMES - 1
    assert set(entry["criteria"]) == {"gtfree:all", "gtfree:textured", "gtfree:textureless"}


def test_a_pair_waits_for_the_motion_source_and_the_rest_is_scored_at_the_end(bag: Path) -> None:
    """/tf logged after the frames: each pair is scored once the source holds its later stamp."""
    known: list[int] = []  # the stamps the motion source has caught up to
    results: list[FrameResult] = []
    config = CoreConfig(
        methods={m: disparity_topic(m) for m in NOISE}, gt_topic=GT_TOPIC,
        left_info_topic=LEFT_INFO, right_info_topic=RIGHT_INFO, egomotion=True,
    )  # fmt: skip
    core = EvaluationCore(config)
    assert core.pairs is not None
    core.pairs.motion = drive_motion
    core.pairs.ready = lambda stamp, frame: bool(known) and known[-1] >= stamp
    with BagSource(bag) as source:
        for topic, log_ns, msg in source.messages(list(config.topics)):
            for frame_set in core.push(topic, msg, log_ns):
                results.append(core.pair(core.score(frame_set)))
                known.append(frame_set.stamp)  # the source catches up just after each frame
    tail = core.finish_pairs()
    assert tail is not None
    waited = [(p.stamp, p.method) for r in results for p in r.motion_pairs]
    ended = [(p.stamp, p.method) for p in tail.motion]
    stamps = [r.stamp for r in results]
    assert sorted(waited + ended) == sorted((s, m) for s in stamps[1:] for m in NOISE)
    assert ended == [(stamps[-1], m) for m in NOISE]  # the last pair waited to the end
    assert all(p.stamp < r.stamp for r in results for p in r.motion_pairs)
