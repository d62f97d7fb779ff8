"""How the results database names its sequences and their sources (one rule for every writer).

``dispeval bag``, ``eval --out`` and ``tune`` (offline and ``--node``) all name a sequence from
its bag or scene folder and record where it came from by these two functions.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path


def sequence_names(bags: Sequence[Path]) -> list[str]:
    """Unique, readable sequence names from bag paths (the stem, suffixed when repeated)."""
    stems = [(path.stem if path.suffix else path.name) or "bag" for path in bags]
    seen: Counter[str] = Counter()
    names = []
    for stem in stems:
        seen[stem] += 1
        names.append(stem if stems.count(stem) == 1 else f"{stem}-{seen[stem]}")
    return names


def bag_location(path: Path) -> str:
    """How the results database names a bag: its resolved absolute path.

    ``bags/x``, ``./bags/x`` and ``/abs/bags/x`` are one bag, so ``--resume`` from any
    spelling (or folder) continues the run, and only another bag is refused.
    """
    return str(Path(path).resolve())
