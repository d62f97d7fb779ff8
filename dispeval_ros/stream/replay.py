"""Feed a recorded bag to a live front end, at the recorded rate or as fast as possible.

Each message goes with its log time, the arrival ``dispeval bag`` uses: a replayed bag's delays
(arrival − header stamp) are the recording's, whatever the replay rate or the wall clock.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from dispeval_ros.io.bags import BagSource


def replay(
    path: Path,
    topics: Sequence[str],
    push: Callable[[str, Any, int], None],
    *,
    rate: float | None = 1.0,
    stop: threading.Event | None = None,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Push every message of ``topics`` in log-time order; returns how many were pushed.

    ``push(topic, msg, log_time)``: the log time (ns) is the message's arrival (``received``
    of :meth:`~dispeval_ros.stream.runner.LiveEvaluator.push`).

    ``rate`` 1.0 keeps the recorded timing, 2.0 plays twice as fast, None as fast as possible.
    ``stop`` ends the replay early (checked between messages).
    """
    pushed = 0
    with BagSource(path) as source:
        started: float | None = None
        first_log = 0
        for topic, log_time, msg in source.messages(list(topics)):
            if stop is not None and stop.is_set():
                break
            if rate is not None and rate > 0:
                if started is None:
                    started, first_log = clock(), log_time
                due = started + (log_time - first_log) / 1e9 / rate
                delay = due - clock()
                if delay > 0:
                    if stop is not None:
                        if stop.wait(delay):
                            break
                    else:
                        sleep(delay)
            push(topic, msg, log_time)
            pushed += 1
    return pushed
