"""The pair stage of the evaluation core (stream/pairs.py): which frames pair, and the numbers.

The values are checked against plain numpy written here from the definition (docs/method.md,
"Temporal measures"): ``tepe`` the mean of ``|(E_t − E_t+1) − (D_t − D_t+1)|`` over the pixels
with GT in both frames (every pixel has an estimate here, so no missing policy applies).
"""

from __future__ import annotations

import numpy as np
import pytest

from dispeval_ros.core.evaluator import Evaluator
from dispeval_ros.stream.pairs import DEFAULT_PAIR_GAP_NS, PairInput, PairStage

MS = 1_000_000
H, W = 24, 32


def gt_of(index: int) -> np.ndarray:
    """A sloped scene drifting by a pixel a frame, with a moving hole of no ground truth."""
    rows, cols = np.mgrid[0:H, 0:W]
    gt = (10.0 + 0.2 * cols + 0.1 * rows + index).astype(np.float32)
    gt[2 + index : 6 + index, 3:9] = np.nan
    return gt


def noisy(gt: np.ndarray, seed: int, sigma: float = 0.5) -> np.ndarray:
    estimate = np.nan_to_num(gt, nan=20.0) + np.random.default_rng(seed).normal(0, sigma, gt.shape)
    return estimate.astype(np.float32)


def numpy_tepe(gt0, gt1, est0, est1) -> tuple[int, float]:
    both = np.isfinite(gt0) & (gt0 > 0) & np.isfinite(gt1) & (gt1 > 0)
    change = gt0.astype(np.float64) - gt1.astype(np.float64)
    error = np.abs((est0.astype(np.float64) - est1.astype(np.float64)) - change)[both]
    return int(both.sum()), float(error.mean())


class Stream:
    """Frames fed to a pair stage as the core hands them over."""

    def __init__(self, gap_ns: int = DEFAULT_PAIR_GAP_NS) -> None:
        self.evaluator = Evaluator(criteria=("all",), missing="ignore")
        self.stage = PairStage(self.evaluator, "dispeval", gap_ns)

    def frame(self, stamp: int, gt: np.ndarray | None, estimates: dict[str, np.ndarray]):
        reference = None if gt is None else self.evaluator.reference(gt)
        prepared = {m: self.stage.prepare(e, None, 0.0) for m, e in estimates.items()}
        return self.stage.add(PairInput(stamp, reference, prepared if gt is not None else {}))


def test_consecutive_frames_give_each_methods_tepe_as_numpy_computes_it() -> None:
    stream = Stream()
    gts = [gt_of(i) for i in range(4)]
    ests = [{"a": noisy(g, i), "b": noisy(g, 10 + i, 0.1)} for i, g in enumerate(gts)]
    assert stream.frame(0, gts[0], ests[0]).scores == {}  # the first frame: no pair yet
    for i in range(1, 4):
        outcome = stream.frame(i * 100 * MS, gts[i], ests[i])
        assert outcome.previous == (i - 1) * 100 * MS
        assert outcome.problems == []
        for method in ("a", "b"):
            n, tepe = numpy_tepe(gts[i - 1], gts[i], ests[i - 1][method], ests[i][method])
            got = outcome.scores[method]["all"]
            assert got["n_pair"] == n
            assert got["tepe"] == pytest.approx(tepe, rel=1e-6)


def test_a_constant_bias_scores_zero_and_added_noise_does_not() -> None:
    stream = Stream()
    stream.frame(0, gt_of(0), {"bias": gt_of(0) + 1, "noise": noisy(gt_of(0), 1)})
    outcome = stream.frame(100 * MS, gt_of(1), {"bias": gt_of(1) + 1, "noise": noisy(gt_of(1), 2)})
    assert outcome.scores["bias"]["all"]["tepe"] == pytest.approx(0.0, abs=1e-6)
    assert outcome.scores["noise"]["all"]["tepe"] > 0.1


def test_a_missing_estimate_ends_the_run_with_one_line_and_a_new_run_starts() -> None:
    stream = Stream()
    est = {"a": noisy(gt_of(0), 0), "b": noisy(gt_of(0), 1)}
    stream.frame(0, gt_of(0), est)
    outcome = stream.frame(100 * MS, gt_of(1), {"a": noisy(gt_of(1), 2)})  # b missed
    assert set(outcome.scores) == {"a"}
    assert outcome.problems == [("b", f"b: no pair 0 → {100 * MS}: b not scored at {100 * MS}")]
    outcome = stream.frame(200 * MS, gt_of(2), {"a": noisy(gt_of(2), 3), "b": noisy(gt_of(2), 4)})
    assert set(outcome.scores) == {"a"}  # b's new run starts here
    assert outcome.problems == []
    outcome = stream.frame(300 * MS, gt_of(3), {"a": noisy(gt_of(3), 5), "b": noisy(gt_of(3), 6)})
    assert set(outcome.scores) == {"a", "b"}


def test_a_frame_whose_ground_truth_failed_ends_every_run() -> None:
    stream = Stream()
    stream.frame(0, gt_of(0), {"a": noisy(gt_of(0), 0)})
    outcome = stream.frame(100 * MS, None, {})
    assert outcome.scores == {}
    assert [m for m, _ in outcome.problems] == ["a"]
    assert stream.frame(200 * MS, gt_of(2), {"a": noisy(gt_of(2), 1)}).scores == {}


def test_frames_further_apart_than_the_pair_gap_are_not_paired() -> None:
    stream = Stream(gap_ns=150 * MS)
    stream.frame(0, gt_of(0), {"a": noisy(gt_of(0), 0)})
    outcome = stream.frame(200 * MS, gt_of(1), {"a": noisy(gt_of(1), 1)})
    assert outcome.scores == {}
    [(method, text)] = outcome.problems
    assert method == "a"
    assert "200 ms apart, more than the pair gap 150 ms" in text
    assert set(stream.frame(300 * MS, gt_of(2), {"a": noisy(gt_of(2), 2)}).scores) == {"a"}


def test_a_frame_out_of_stamp_order_is_a_problem_line_not_a_traceback() -> None:
    stream = Stream()
    stream.frame(500 * MS, gt_of(0), {"a": noisy(gt_of(0), 0)})
    outcome = stream.frame(400 * MS, gt_of(1), {"a": noisy(gt_of(1), 1)})
    assert outcome.scores == {}
    [(method, text)] = outcome.problems
    assert method is None
    assert "not after the previous frame's" in text


def test_a_size_change_between_frames_is_a_problem_of_the_pair() -> None:
    stream = Stream()
    stream.frame(0, gt_of(0), {"a": noisy(gt_of(0), 0)})
    small = gt_of(1)[:, :16]
    outcome = stream.frame(100 * MS, small, {"a": noisy(small, 1)})
    assert outcome.scores == {}
    [(method, text)] = outcome.problems
    assert method == "a"
    assert text.startswith(f"a: no pair 0 → {100 * MS}: ")
