"""The test-bed disparity node for ``tune --node`` tests, optionally misbehaving (a subprocess).

``python tune_target.py NAMESPACE [--refuse NAME=VALUE] [--die-after N] [--delay S]``: the
test-bed node in NAMESPACE that refuses one value through its parameter callback (as a real node
may refuse what the space allows), that dies (``os._exit``, no goodbye) when a frame comes after
N maps published, or that takes S seconds more per map.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import time
from collections.abc import Sequence
from typing import Any

import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import SingleThreadedExecutor

from dispeval_ros.ros.testbed_disparity import TestbedDisparityNode


class Target(TestbedDisparityNode):
    """The test-bed node with a refused value and a planned death."""

    def __init__(
        self,
        namespace: str,
        refuse: tuple[str, float] | None,
        die_after: int | None,
        delay: float = 0.0,
    ) -> None:
        self._refuse = refuse
        super().__init__(namespace=namespace)
        self._die_after = die_after
        self._delay = delay

    def _disparity(self, members: dict[Any, Any]) -> Any:
        time.sleep(self._delay)  # a slow node: a sweep long enough to interrupt
        return super()._disparity(members)

    def _on_set(self, parameters: Sequence[Any]) -> SetParametersResult:
        if self._refuse is not None:
            name, value = self._refuse
            if any(p.name == name and p.value == value for p in parameters):
                return SetParametersResult(successful=False, reason=f"{name} {value:g} not here")
        return super()._on_set(parameters)

    def _on_input(self, topic: str, msg: Any) -> None:
        if self._die_after is not None and self.frames_published >= self._die_after:
            os._exit(3)  # on the first input after the last map (so that map was delivered)
        super()._on_input(topic, msg)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("namespace")
    parser.add_argument("--refuse")
    parser.add_argument("--die-after", type=int)
    parser.add_argument("--delay", type=float, default=0.0)
    args = parser.parse_args()
    refuse = None
    if args.refuse:
        name, value = args.refuse.split("=")
        refuse = (name, float(value))
    rclpy.init()
    executor = SingleThreadedExecutor()
    executor.add_node(Target(args.namespace, refuse, args.die_after, args.delay))
    with contextlib.suppress(KeyboardInterrupt):
        executor.spin()


if __name__ == "__main__":
    main()
