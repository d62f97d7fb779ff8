"""What stereo_image_proc's disparity node does, without ROS: the test-bed's stand-in for it.

``dispeval tune --node`` drives a running disparity node through its parameters; the test-bed
node (:mod:`dispeval_ros.ros.testbed_disparity`) has the same interface (topics, parameter
names, ranges and defaults from :mod:`.node_parameters`, OpenCV inside) and takes its logic from
here: the matcher of its current parameters, the message fields the real node writes
(``f`` = the right camera's fx, ``T`` = the baseline, the search range, ``delta_d`` = 1/16, the
valid window as its ``imageCb`` computes it, values ``d_fp/16 − (cx_l − cx_r)``), and the exact
time synchronisation of its four inputs.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dispeval_ros.errors import ConfigurationError
from dispeval_ros.testbed.methods import StereoMethod
from dispeval_ros.testbed.node_parameters import (
    ALGORITHM_PARAMETER,
    FAMILIES,
    PARAMETERS,
    check_family,
    stereo_method,
)

INPUTS = ("left/image_rect", "left/camera_info", "right/image_rect", "right/camera_info")
"""The node's input topics (relative: remap or namespace them), as stereo_image_proc's."""
OUTPUT = "disparity"
"""Its output topic (``stereo_msgs/DisparityImage``)."""
DELTA_D = 1.0 / 16.0
"""OpenCV's disparities are fixed point with 4 fractional bits."""


@dataclass(frozen=True)
class DisparityOutput:
    """The fields of one ``stereo_msgs/DisparityImage`` the node publishes."""

    disparity: np.ndarray
    f: float
    t: float
    min_disparity: float
    max_disparity: float
    delta_d: float
    valid_window: tuple[int, int, int, int]
    """``(x_offset, y_offset, width, height)``, as the node computes it (it may wrap around:
    the real node's are unsigned fields)."""


def node_defaults() -> dict[str, int | float]:
    """Every parameter the node declares with its default (``stereo_algorithm`` first)."""
    values: dict[str, int | float] = {ALGORITHM_PARAMETER: FAMILIES["bm"]}
    for parameter in PARAMETERS.values():
        values[parameter.name] = (
            float(parameter.default) if parameter.floating else parameter.default
        )
    return values


@dataclass
class DisparityNodeModel:
    """The node's parameters and the matcher they make (rebuilt when they change)."""

    values: dict[str, int | float] = field(default_factory=node_defaults)
    _method: StereoMethod | None = field(default=None, init=False, repr=False)

    @property
    def family(self) -> str:
        """``bm`` or ``sgbm``, as ``stereo_algorithm`` says."""
        return check_family(int(self.values[ALGORITHM_PARAMETER]), ALGORITHM_PARAMETER)

    def update(self, changes: Mapping[str, Any]) -> None:
        """Take new values (all or none): one line naming what the node would refuse.

        Refused: an unknown name, a value off its declared range or step, an unknown
        ``stereo_algorithm``, and a combination the matcher cannot run (``P2 ≤ P1`` for SGBM).
        """
        proposed = dict(self.values)
        for name, value in changes.items():
            if name == ALGORITHM_PARAMETER:
                proposed[name] = FAMILIES[check_family(value, ALGORITHM_PARAMETER)]
                continue
            parameter = PARAMETERS.get(name)
            if parameter is None:
                raise ConfigurationError(f"the disparity node has no parameter {name!r}")
            number = parameter.check(value, "the disparity node")
            proposed[name] = float(number) if parameter.floating else number
        method = _method_of(proposed)
        self.values, self._method = proposed, method

    def method(self) -> StereoMethod:
        """The OpenCV matcher of the current values."""
        if self._method is None:
            self._method = _method_of(self.values)
        return self._method

    def process(
        self, left: np.ndarray, right: np.ndarray, fx_right: float, baseline: float, doffs: float
    ) -> DisparityOutput:
        """One rectified mono8 pair → the message's fields (``doffs = cx_l − cx_r``)."""
        method = self.method()
        values = method.compute(left, right)
        if doffs:  # OpenCV's convertTo: d_fp / 16 − (cx_l − cx_r), in float32
            values = (values.astype(np.float64) - doffs).astype(np.float32)
        border = method.block_size // 2
        low = method.min_disparity
        x_left = method.num_disparities + low + border - 1
        reach = border + low if low >= 0 else max(border, -low)
        height, width = values.shape
        x_right, top, bottom = width - 1 - reach, border, height - 1 - border
        return DisparityOutput(
            values,
            float(fx_right),
            float(baseline),
            float(low),
            float(method.max_disparity),
            DELTA_D,
            (x_left, top, x_right - x_left, bottom - top),
        )


def _method_of(values: Mapping[str, int | float]) -> StereoMethod:
    family = check_family(int(values[ALGORITHM_PARAMETER]), ALGORITHM_PARAMETER)
    chosen = {p.name: int(values[p.name]) for p in PARAMETERS.values() if family in p.families}
    return stereo_method("disparity_node", family, chosen)


class ExactTimeSync:
    """Message sets whose members all carry the same stamp (message_filters' ExactTime).

    ``add(slot, stamp, msg)`` returns the complete set ``{slot: msg}`` once every slot has a
    message of that stamp; at most ``queue_size`` incomplete stamps are kept (the oldest is
    dropped, as the real synchroniser does), and :attr:`dropped` counts them.
    """

    def __init__(self, slots: tuple[Hashable, ...], queue_size: int = 5) -> None:
        if queue_size < 1:
            raise ConfigurationError(f"queue_size must be at least 1, got {queue_size}")
        self.slots = slots
        self.queue_size = queue_size
        self.dropped = 0
        self._pending: dict[int, dict[Hashable, Any]] = {}

    def add(self, slot: Hashable, stamp: int, msg: Any) -> dict[Hashable, Any] | None:
        """Add one message; the complete set of its stamp, if this completed it."""
        if slot not in self.slots:
            raise ConfigurationError(f"unknown slot {slot!r}; the slots are {self.slots}")
        members = self._pending.setdefault(stamp, {})
        members[slot] = msg
        if len(members) == len(self.slots):
            del self._pending[stamp]
            for older in [s for s in self._pending if s < stamp]:  # never completed: gone
                del self._pending[older]
                self.dropped += 1
            return members
        while len(self._pending) > self.queue_size:
            del self._pending[min(self._pending)]
            self.dropped += 1
        return None
