"""What the Dask benches share: the throughput model of units on W workers and one driver.

A unit costs ``unit_cost`` s on a worker and ``driver_cost`` s at the driver (writing its rows,
the Dask round trip of its payload); the driver writes one unit at a time, so W workers give at
most ``min(W / unit_cost, 1 / driver_cost)`` units/s and the driver saturates at ``unit_cost /
driver_cost`` workers. Machines with fewer cores than that are simulated by this model.
"""

from __future__ import annotations

import pickle
import time
from collections.abc import Sequence
from typing import Any

WORKERS = (1, 2, 4, 8, 16, 32, 64, 128, 256)


def echo(payload: bytes) -> int:
    """A Dask task that only carries a unit's payload there and back."""
    return len(payload)


def round_trip_cost(client: Any, outcomes: Sequence[object]) -> tuple[float, float]:
    """Seconds per task of the Dask round trip of each outcome's pickled payload, and its kB."""
    payloads = [pickle.dumps(outcome) for outcome in outcomes]
    started = time.perf_counter()
    client.gather([client.submit(echo, payload, pure=False) for payload in payloads])
    return (time.perf_counter() - started) / len(payloads), sum(map(len, payloads)) / 1e3 / len(
        payloads
    )


def print_scaling(unit_cost: float, driver_cost: float, units: int | None = None) -> None:
    """The model's table: units/s, speed-up (and, given ``units``, the run's time) per W."""
    print(
        f"driver saturates at about {unit_cost / driver_cost:.0f} workers "
        f"({1 / driver_cost:.0f} units/s)"
    )
    header = "workers  units/s (model)  speed-up"
    print(header + ("  time for the units" if units else ""))
    for workers in WORKERS:
        rate = min(workers / unit_cost, 1 / driver_cost)
        line = f"{workers:7d}  {rate:15.1f}  {rate * unit_cost:7.1f}×"
        print(line + (f"  {units / rate:10.1f} s" if units else ""))
