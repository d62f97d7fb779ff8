"""Protocols dispatch through their own functions: no name chains, no silent default."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dispeval_ros.core.protocols import (
    PROTOCOLS,
    FrameData,
    evaluate_frame,
    get_protocol,
    summarize_frames,
)
from dispeval_ros.errors import ConfigurationError


def _frame() -> tuple[FrameData, np.ndarray]:
    rng = np.random.default_rng(3)
    gt = rng.uniform(1.0, 40.0, (12, 16)).astype(np.float32)
    estimate = (gt + rng.normal(0.0, 2.0, gt.shape)).astype(np.float32)
    return FrameData("f", gt), estimate


def test_unknown_protocol_name_is_an_error() -> None:
    data, estimate = _frame()
    for call in (
        lambda: get_protocol("kitti"),
        lambda: evaluate_frame("kitti", data, estimate),
        lambda: summarize_frames("kitti", []),
    ):
        with pytest.raises(ConfigurationError, match="unknown protocol 'kitti'; choose from"):
            call()


@pytest.mark.parametrize("name", list(PROTOCOLS))
def test_a_protocol_scores_with_its_own_functions_whatever_its_name(name: str) -> None:
    """A renamed copy scores as its original (a name chain would fall to ETH3D's ``else``)."""
    data, estimate = _frame()
    renamed = dataclasses.replace(PROTOCOLS[name], name="renamed")
    want = evaluate_frame(name, data, estimate)
    have = evaluate_frame(renamed, data, estimate)
    assert have.values == want.values
    assert list(have.values["all" if "all" in have.values else "occ"]) == list(renamed.columns)
    assert summarize_frames(renamed, [have]) == summarize_frames(name, [want])
