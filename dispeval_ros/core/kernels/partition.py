"""The partition: pixels into cells in run order, and the valid-point scans of the GT."""

from __future__ import annotations

import numpy as np

from dispeval_ros.core.kernels._jit import njit

#: Pixels per run of one cell, on average, from which :func:`partition_cells` works run by run.
RUN_PIXELS = 8


@njit(cache=True, nogil=True, inline="always")
def _run_end(flat_cells: np.ndarray, start: np.uint64, end: np.uint64) -> np.uint64:
    """Where the run of equal cells that begins at ``start`` ends (16 at a time, vectorised)."""
    cell = flat_cells[start]
    stop = start + np.uint64(1)
    chunk = np.uint64(16)
    while stop + chunk <= end:
        differ = np.int32(0)
        for offset in range(16):
            differ |= flat_cells[stop + np.uint64(offset)] ^ cell
        if differ != 0:
            break
        stop += chunk
    while stop < end and flat_cells[stop] == cell:
        stop += np.uint64(1)
    return stop


@njit(cache=True, nogil=True)
def partition_cells(
    flat_valid: np.ndarray,
    flat_occluded: np.ndarray,
    flat_near_jump: np.ndarray,
    visibility_stride: int,
    flat_values: np.ndarray,
    low: float,
    high: float,
    depth_stride: int,
    flat_labels: np.ndarray,
    labels_stride: int,
    flat_cells: np.ndarray,
    next_slot: np.ndarray,
    offsets: np.ndarray,
    order: np.ndarray,
    sorted_values: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """The cell of every pixel, the evaluated pixels sorted by cell and their values gathered.

    A valid pixel's cell is ``visibility · visibility_stride + depth · depth_stride + label ·
    labels_stride`` with the visibility class (0 occluded, else 1 near a jump, else 2) and the
    depth class (0 above ``high``, 1 in ``(low, high]``, 2 otherwise) computed here, and
    ``label`` from a label image (several criterion sets folded into one); ``-1`` elsewhere.
    An input whose stride is 0 is not used (any array of the right type will do; for the labels
    even ``flat_cells``).
    Then a stable counting sort: ``order[offsets[c]:offsets[c + 1]]`` are cell ``c``'s
    pixels, and ``sorted_values`` (unless empty) ``flat_values`` in that order. Dense GT gives
    long runs of one cell along image rows: whole runs (at least :data:`RUN_PIXELS` pixels on
    average) are counted and placed with vectorised copies; otherwise (sparse GT) pixels are
    counted one at a time on four interleaved counters. The caller allocates (kernels that
    allocate and return arrays take twice as long to compile): ``next_slot`` zeros
    ``(4, cells + 1)``, ``offsets`` ``(cells + 1)``, ``order`` and ``sorted_values`` one entry
    per valid pixel.
    """
    n_cells = offsets.shape[0] - 1
    pixels = flat_cells.shape[0]
    for i in range(pixels):  # branch-free: vectorised
        visibility = 0 if flat_occluded[i] else (1 if flat_near_jump[i] else 2)
        v = flat_values[i]
        depth = 0 if v > high else (1 if v > low else 2)
        c = visibility * visibility_stride + depth * depth_stride
        flat_cells[i] = c if flat_valid[i] else -1
    if labels_stride != 0:  # a loop of its own: ``flat_labels`` may be ``flat_cells`` otherwise
        for i in range(pixels):  # a negative label leaves the pixel out
            c = flat_cells[i] + flat_labels[i] * labels_stride
            flat_cells[i] = max(c, -1) if flat_valid[i] else -1
    # Indices are unsigned below (cells are >= -1): no negative-index wrap-around is computed,
    # which lets the loops vectorise.
    end = np.uint64(pixels)
    changes = 0
    for i in range(1, pixels):  # vectorised
        changes += flat_cells[np.uint64(i)] != flat_cells[np.uint64(i - 1)]
    long_runs = changes * RUN_PIXELS < pixels  # dense GT: count and place whole runs
    if long_runs:
        start = np.uint64(0)
        while start < end:
            stop = _run_end(flat_cells, start, end)
            next_slot[0, np.uint64(flat_cells[start] + 1)] += np.int64(stop - start)
            start = stop
    else:  # short runs (sparse GT): one pixel at a time, interleaved counters
        for i in range(pixels):
            next_slot[np.uint64(i & 3), np.uint64(flat_cells[i] + 1)] += 1
    offsets[0] = 0
    for c in range(n_cells):
        offsets[c + 1] = offsets[c] + next_slot[0, c + 1] + next_slot[1, c + 1]
        offsets[c + 1] += next_slot[2, c + 1] + next_slot[3, c + 1]
    for c in range(n_cells):
        next_slot[0, c] = offsets[c]  # from here on: where each cell's next pixel goes
    slots = next_slot[0]
    gather = sorted_values.shape[0] > 0
    if long_runs:
        start = np.uint64(0)
        while start < end:
            cell = flat_cells[start]
            stop = _run_end(flat_cells, start, end)
            if cell >= 0:
                slot = np.uint64(slots[cell])
                length = stop - start
                for k in range(length):
                    order[slot + np.uint64(k)] = np.int32(start + np.uint64(k))
                if gather:
                    for k in range(length):
                        sorted_values[slot + np.uint64(k)] = flat_values[start + np.uint64(k)]
                slots[cell] = np.int64(slot + length)
            start = stop
        return
    current = np.uint64(0)
    position = np.uint64(slots[0])
    for i in range(pixels):  # a run of one cell is placed from a register
        cell = flat_cells[i]
        if cell >= 0:
            c = np.uint64(cell)
            if c != current:
                slots[current] = position
                current = c
                position = np.uint64(slots[c])
            order[position] = i
            if gather:
                sorted_values[position] = flat_values[i]
            position += np.uint64(1)


@njit(cache=True, nogil=True)
def valid_points(flat_values: np.ndarray, flat_valid: np.ndarray) -> None:  # pragma: no cover
    """``flat_valid``: each value is finite and > 0 (NaN fails both tests); vectorised."""
    for k in range(flat_values.shape[0]):
        i = np.uint64(k)  # unsigned: no wrap-around test in the loop
        flat_valid[i] = (flat_values[i] > 0) & (flat_values[i] < np.inf)


@njit(cache=True, nogil=True)
def pack_valid(
    flat_values: np.ndarray, flat_valid: np.ndarray, packed: np.ndarray
) -> int:  # pragma: no cover - compiled
    """Copy the valid values to the front of ``packed`` (branch-free); their number."""
    count = 0
    for i in range(flat_values.shape[0]):
        packed[count] = flat_values[i]  # overwritten by the next value unless this one is valid
        count += 1 if flat_valid[i] else 0
    return count


@njit(cache=True, nogil=True)
def valid_range(
    bits: np.ndarray, valid: np.ndarray, limits: np.ndarray
) -> None:  # pragma: no cover
    """The bit patterns of the smallest and largest valid value, in ``limits`` (vectorised).

    ``bits``: the values viewed as signed integers of their size. Valid values are finite and
    > 0, whose bit patterns sort as the values do, and integer minima vectorise where float
    ones (NaN rules) do not. The caller fills ``limits`` with the type's largest value and −1.
    """
    top = limits[0]
    bottom = limits[1]
    lowest = top
    highest = bottom
    for k in range(bits.shape[0]):
        i = np.uint64(k)
        lowest = min(lowest, bits[i] if valid[i] else top)
        highest = max(highest, bits[i] if valid[i] else bottom)
    limits[0] = lowest
    limits[1] = highest
