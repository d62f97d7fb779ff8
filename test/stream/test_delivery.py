"""Delivery records and the ledger: counts a summarizer stores, frames it never received."""

from __future__ import annotations

import pytest

from dispeval_ros.errors import InputError
from dispeval_ros.io.store import MatchCounts
from dispeval_ros.stream.core import MethodCounts
from dispeval_ros.stream.delivery import (
    DELIVERY_STATUS,
    DeliveryLedger,
    delivery_record,
    read_delivery,
)
from dispeval_ros.stream.vectors import (
    ERROR,
    GROUND_TRUTH,
    OK,
    StatusRecord,
    problem_status,
    read_problem,
)


def counts(**methods: tuple[int, int, int, int]) -> dict[str, MethodCounts]:
    return {name: MethodCounts(*values) for name, values in methods.items()}


def test_record_round_trips() -> None:
    sent = counts(a=(3, 1, 2, 0), b_2=(0, 0, 0, 4))
    record = delivery_record("/dispeval_evaluator@1-ab", 7, sent, final=True)
    assert record.name == DELIVERY_STATUS
    assert record.level == OK
    delivery = read_delivery(record)
    assert delivery is not None
    assert delivery.source == "/dispeval_evaluator@1-ab"
    assert (delivery.index, delivery.final) == (7, True)
    assert delivery.counts == sent


def test_other_statuses_are_not_deliveries_and_bad_ones_are_one_line() -> None:
    assert read_delivery(StatusRecord("a", "/t", OK, "", (("all/bmp", "1.0"),))) is None
    broken = StatusRecord(DELIVERY_STATUS, "/e", OK, "", (("index", "x"),))
    with pytest.raises(InputError, match="malformed delivery record from /e"):
        read_delivery(broken)


def test_problem_statuses_of_both_forms_are_read() -> None:
    assert read_problem(problem_status("a", "/t/a", "size mismatch")) == ("a", "size mismatch")
    assert read_problem(problem_status(None, "/gt", "no GT")) == (None, "no GT")
    assert read_problem(StatusRecord(GROUND_TRUTH, "/gt", ERROR, "empty", ())) == (None, "empty")
    assert read_problem(StatusRecord("a", "/t", ERROR, "alarm", (("all/bmp", "50"),))) is None
    assert read_problem(StatusRecord("a", "/t", OK, "", ())) is None


def test_every_scored_frame_is_stored_or_counted_lost() -> None:
    """Arrays 3 and 5 of 6 never arrive: their frames are counted as dropped, per method."""
    ledger = DeliveryLedger()
    # "a" is in every frame, "b" in the even ones; the evaluator also counted unmatched etc.
    methods_of = {k: ["a", "b"] if k % 2 == 0 else ["a"] for k in range(1, 7)}
    for k in (1, 2, 4, 6):
        matched_b = sum(1 for j in range(1, k + 1) if j % 2 == 0)
        sent = counts(a=(k, 1, 0, 0), b=(matched_b, 0, 2, 1), never=(0, 5, 0, 0))
        delivery = read_delivery(delivery_record("e1", k, sent))
        assert delivery is not None
        ledger.add(delivery, methods_of[k])
    final = read_delivery(
        delivery_record(
            "e1", 6, counts(a=(6, 1, 0, 0), b=(3, 0, 2, 1), never=(0, 5, 0, 0)), final=True
        )
    )
    assert final is not None
    ledger.add(final)
    assert ledger.lost_arrays() == 2
    totals, messages = ledger.checkpoint(closing=True)
    # a: frames 3 and 5 lost; b: none of its frames (2, 4, 6) lost; never: matched nothing
    assert totals == {
        "a": MatchCounts(0, 1, 2, 0),
        "b": MatchCounts(0, 0, 2, 1),
        "never": MatchCounts(0, 5, 0, 0),
    }
    assert messages == [
        "2 scored frame(s) of evaluator e1 never reached the summarizer (it fell behind or the "
        "link lost them); counted as dropped"
    ]
    assert ledger.checkpoint(closing=True) == (
        {m: MatchCounts(0, 0, 0, 0) for m in ("a", "b", "never")},
        [],
    )


def test_checkpoints_split_counts_by_sequence_and_add_up() -> None:
    ledger = DeliveryLedger()
    first = read_delivery(delivery_record("e", 1, counts(a=(1, 2, 0, 0))))
    second = read_delivery(delivery_record("e", 2, counts(a=(2, 5, 1, 0))))
    assert first is not None
    assert second is not None
    ledger.add(first, ["a"])
    early, _ = ledger.checkpoint()
    ledger.add(second, ["a"])
    late, messages = ledger.checkpoint(closing=True)
    assert early == {"a": MatchCounts(0, 2, 0, 0)}
    assert late == {"a": MatchCounts(0, 3, 1, 0)}
    assert messages == [
        "no final counts from evaluator e (stopped without finishing?): its counts as of its "
        "scores array 2 are stored"
    ]


def test_two_evaluators_are_kept_apart_and_summed() -> None:
    ledger = DeliveryLedger()
    for source, method in (("e1", "a"), ("e2", "b")):
        for k in (1, 3):  # array 2 of each is lost
            delivery = read_delivery(delivery_record(source, k, {method: MethodCounts(k, 0, 0, 0)}))
            assert delivery is not None
            ledger.add(delivery, [method])
        final = read_delivery(
            delivery_record(source, 3, {method: MethodCounts(3, 0, 0, 0)}, final=True)
        )
        assert final is not None
        ledger.add(final)
    totals, messages = ledger.checkpoint(closing=True)
    assert totals == {"a": MatchCounts(0, 0, 1, 0), "b": MatchCounts(0, 0, 1, 0)}
    assert len(messages) == 2
