"""Alarm thresholds on score values (``criterion/measure=limit``): the level of a status.

The evaluator node and ``dispeval live`` take them as string arrays (``alarm_warn``,
``alarm_error``); :func:`~dispeval_ros.stream.vectors.scores_status` applies them. Refused with
the options, in one line, is what could never fire.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field

from dispeval_ros.core.criteria.base import DEPTH, LEGACY, VISIBILITY
from dispeval_ros.core.criteria.regions import TEXTURE
from dispeval_ros.core.measures import GT_FREE_PREFIX, HIGHER_IS_BETTER, parse_measures
from dispeval_ros.errors import ConfigurationError

OK, WARN, ERROR = 0, 1, 2
"""Diagnostic levels (``diagnostic_msgs/DiagnosticStatus``)."""
DELAY_ALARM = "latency/delay_ms"
"""The alarm key of an estimate's delay (ms): ``latency/delay_ms=50`` beside the score ones."""
CRITERION_NAMES = tuple(
    dict.fromkeys(("all", *VISIBILITY, *DEPTH, *LEGACY, *TEXTURE, "roi", "elsewhere", "unlabelled"))
)
"""The criteria a stream's frame can carry (each also as ``gtfree:NAME``): an alarm on any
other name could never fire, so it is refused with the options."""


@dataclass(frozen=True)
class AlarmThresholds:
    """Alarm levels on ``criterion/measure`` values: above ``warn`` → WARN, above ``error`` → ERROR.

    For density (higher is better) the comparison is reversed: below ``warn`` → WARN.
    """

    warn: Mapping[str, float] = field(default_factory=dict)
    error: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def parse(
        cls,
        warn: Sequence[str],
        error: Sequence[str],
        scored: Collection[str] | None = None,
    ) -> AlarmThresholds:
        """From ``criterion/measure=value`` strings (as ROS string-array parameters).

        Refuses (one line) what could never alarm: a criterion or measure that does not exist,
        a measure not among ``scored`` (when given), a value that is not a finite number.
        """
        return cls(_parse_limits(warn, "warn", scored), _parse_limits(error, "error", scored))

    def level(self, key: str, value: float) -> int:
        """The alarm level of one ``criterion/measure`` value (NaN never alarms)."""
        if math.isnan(value):
            return OK
        lower_is_bad = key.rpartition("/")[2] in HIGHER_IS_BETTER
        for level, limits in ((ERROR, self.error), (WARN, self.warn)):
            limit = limits.get(key)
            if limit is not None and (value < limit if lower_is_bad else value > limit):
                return level
        return OK


def _parse_limits(
    items: Sequence[str], what: str, scored: Collection[str] | None
) -> dict[str, float]:
    limits = {}
    for item in items:
        key, sep, value = item.partition("=")
        try:
            if not sep or "/" not in key:
                raise ValueError(item)
            limit = float(value)
        except ValueError:
            raise ConfigurationError(
                f"alarm {what} threshold '{item}' is not CRITERION/MEASURE=NUMBER (e.g. all/bmp=20, "
                f"{DELAY_ALARM}=50)"
            ) from None
        key = key.strip()
        why = _never_alarms(key, limit, scored)
        if why is not None:
            raise ConfigurationError(f"alarm {what} threshold '{item}': {why}")
        limits[key] = limit
    return limits


def _never_alarms(key: str, limit: float, scored: Collection[str] | None) -> str | None:
    """Why an alarm on ``key`` at ``limit`` could never fire, or None."""
    criterion, _, measure = key.rpartition("/")
    if not math.isfinite(limit):
        return f"the limit must be a finite number, got {limit}"
    if key == DELAY_ALARM:  # the latency diagnostic: on every status with an arrival
        return None
    if criterion.removeprefix(GT_FREE_PREFIX) not in CRITERION_NAMES:
        return (
            f"no criterion '{criterion}'; known: {', '.join(CRITERION_NAMES)} "
            f"(ground-truth-free ones as {GT_FREE_PREFIX}NAME)"
        )
    try:
        parse_measures([measure])
    except ConfigurationError as error:
        return str(error)
    if scored is not None and measure not in scored:
        return f"measure '{measure}' is not among the measures scored ({', '.join(scored)})"
    return None
