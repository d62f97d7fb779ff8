"""The kernels' one cache set-up: every kernel module takes ``njit`` from here, so it runs first.

numba caches each compiled kernel on disk next to its source file (``__pycache__`` of this
package), keyed by that file's content: :func:`~dispeval_ros.jitcache.ensure_cache_location`
must pick a writable place before the first ``@njit(cache=True)`` runs.
"""

from __future__ import annotations

from pathlib import Path

from numba import njit

from dispeval_ros.jitcache import ensure_cache_location

ensure_cache_location(Path(__file__).resolve().parent)  # before any kernel is decorated

# Floating-point flags that allow reassociation (vectorised reductions) but keep NaN/inf
# semantics, so a stray non-finite value can never be optimised into a wrong comparison.
_FAST = {"reassoc", "contract", "nsz", "arcp"}

__all__ = ["_FAST", "njit"]
