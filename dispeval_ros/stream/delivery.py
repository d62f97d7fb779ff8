"""What an evaluator delivered to a summarizer that runs apart from it (ROS nodes, DDS).

Every scores array an evaluator publishes carries one more status, the *delivery record*: the
evaluator's id, the array's 1-based index, and its per-method counts so far (matched, unmatched,
dropped, failed); at shutdown it publishes a last, *final* record alone. A summarizer reading
them knows, without guessing:

- the unmatched / dropped / failed counts to store beside the frames, as ``dispeval bag`` does;
- how many scored frames never reached it (a lagging subscriber whose history overflowed, a
  lossy link): the indexes it did not see, and per method the evaluator's matched count minus
  what arrived. Those are stored as dropped, with a problem saying why, so for every frame the
  evaluator scored the database either holds it or counts it as lost.

The intermediate records carry counts taken while later frames may already be scored, so only a
final record gives exact per-method counts; without one (the evaluator was killed) the ledger
uses the latest record and says so in a problem.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from dispeval_ros.core.records import MatchCounts
from dispeval_ros.errors import InputError
from dispeval_ros.stream.core import MethodCounts
from dispeval_ros.stream.vectors import OK, StatusRecord

DELIVERY_STATUS = "dispeval:delivery"
"""Status name of the delivery record; no method can have it (method names are identifiers)."""
COUNT_FIELDS = ("matched", "unmatched", "dropped", "failed")


@dataclass(frozen=True)
class Delivery:
    """One delivery record, read back."""

    source: str
    index: int
    """How many scores arrays the evaluator had published, this one included."""
    final: bool
    counts: dict[str, MethodCounts]


def delivery_record(
    source: str, index: int, counts: Mapping[str, MethodCounts], *, final: bool = False
) -> StatusRecord:
    """The delivery status an evaluator adds to its ``index``-th scores array (or sends last)."""
    values = [("index", str(index)), ("final", "1" if final else "0")]
    for method, method_counts in counts.items():
        values.extend(
            (f"{method}/{name}", str(getattr(method_counts, name))) for name in COUNT_FIELDS
        )
    what = "final counts" if final else f"scores array {index}"
    return StatusRecord(DELIVERY_STATUS, source, OK, f"{what} of this evaluator", tuple(values))


def read_delivery(record: StatusRecord) -> Delivery | None:
    """The delivery record among a frame's statuses; None for any other status."""
    if record.name != DELIVERY_STATUS:
        return None
    values = dict(record.values)
    try:
        counts: dict[str, dict[str, int]] = {}
        for key, value in record.values:
            method, _, name = key.rpartition("/")
            if method and name in COUNT_FIELDS:
                counts.setdefault(method, {})[name] = int(value)
        return Delivery(
            source=record.hardware_id,
            index=int(values["index"]),
            final=values.get("final") == "1",
            counts={method: MethodCounts(**fields) for method, fields in counts.items()},
        )
    except (KeyError, ValueError, TypeError) as error:
        raise InputError(
            f"a malformed delivery record from {record.hardware_id}: {error}"
        ) from None


@dataclass
class _Source:
    """What arrived from one evaluator."""

    arrays: int = 0
    highest: int = 0
    latest: Delivery | None = None
    final: bool = False
    methods: dict[str, int] = field(default_factory=dict)
    """Per method: scores that arrived."""
    booked: dict[str, MatchCounts] = field(default_factory=dict)
    """Per method: counts already given to earlier sequences."""
    booked_lost: int = 0


class DeliveryLedger:
    """Per evaluator: what arrived, the evaluator's own counts, and what was lost on the way."""

    def __init__(self) -> None:
        self._sources: dict[str, _Source] = {}

    def add(self, delivery: Delivery, methods: Iterable[str] = ()) -> None:
        """A delivery record and the methods whose scores came with it (none for a final)."""
        source = self._sources.setdefault(delivery.source, _Source())
        if not delivery.final:
            source.arrays += 1
            for method in methods:
                source.methods[method] = source.methods.get(method, 0) + 1
        newer = source.latest is None or delivery.final or delivery.index >= source.latest.index
        if newer and not source.final:
            source.latest = delivery
        source.final = source.final or delivery.final
        source.highest = max(source.highest, delivery.index)

    def lost_arrays(self) -> int:
        """Scores arrays published but never received, over every evaluator so far."""
        return sum(source.highest - source.arrays for source in self._sources.values())

    def checkpoint(self, *, closing: bool = False) -> tuple[dict[str, MatchCounts], list[str]]:
        """Counts and problem messages since the previous checkpoint (one per sequence).

        The counts are the evaluators' unmatched, dropped and failed (matched stays 0: the
        stored frames count as matched themselves). ``closing`` (the last checkpoint) adds,
        per method, the scored frames that never arrived to dropped: only then are the
        evaluator's counts final.
        """
        totals: dict[str, MatchCounts] = {}
        messages: list[str] = []
        for name, source in self._sources.items():
            if source.latest is None:
                continue
            lost = source.highest - source.arrays
            if lost > source.booked_lost:
                messages.append(
                    f"{lost - source.booked_lost} scored frame(s) of evaluator {name} never "
                    "reached the summarizer (it fell behind or the link lost them); counted as "
                    "dropped"
                )
            source.booked_lost = lost
            if closing and not source.final:
                messages.append(
                    f"no final counts from evaluator {name} (stopped without finishing?): its "
                    f"counts as of its scores array {source.latest.index} are stored"
                )
            for method, counts in source.latest.counts.items():
                lost_here = counts.matched - source.methods.get(method, 0) if closing else 0
                now = MatchCounts(
                    0, counts.unmatched, counts.dropped + max(0, lost_here), counts.failed
                )
                before = source.booked.get(method, MatchCounts(0, 0, 0, 0))
                source.booked[method] = now
                previous = totals.get(method, MatchCounts(0, 0, 0, 0))
                totals[method] = MatchCounts(
                    0,
                    previous.unmatched + now.unmatched - before.unmatched,
                    previous.dropped + now.dropped - before.dropped,
                    previous.failed + now.failed - before.failed,
                )
        return totals, messages


ProblemRow = tuple[int | None, str | None, str]
"""A problem as a summarizer stores it: stamp (None: not of one frame), method, message."""


class CountsBook:
    """What a summarizer stores with each sequence beside its frames (ROS and DDS alike).

    The evaluators' counts come from their delivery records (:attr:`ledger`); the problems
    (:attr:`problems`) are those that arrived since the previous checkpoint.
    """

    def __init__(self) -> None:
        self.ledger = DeliveryLedger()
        self.problems: list[ProblemRow] = []

    def checkpoint(self, *, closing: bool) -> tuple[dict[str, MatchCounts], list[ProblemRow]]:
        """Counts and problems since the previous checkpoint (:meth:`DeliveryLedger.checkpoint`).

        The ledger's own messages (frames lost on the way, no final counts) come last.
        """
        counts, messages = self.ledger.checkpoint(closing=closing)
        problems = [*self.problems, *((None, None, text) for text in messages)]
        self.problems = []
        return counts, problems
