"""Every benchmark under ``bench/`` still starts: its imports resolve and ``--help`` answers.

The benches are run by hand (they time things; nothing asserts a timing), so nothing else
notices when a module they import moves.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHES = sorted((ROOT / "bench").glob("bench_*.py"))


def test_there_are_benches():
    assert len(BENCHES) >= 10


@pytest.mark.parametrize("bench", BENCHES, ids=[b.stem for b in BENCHES])
def test_a_bench_starts(bench: Path):
    path = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    done = subprocess.run(
        [sys.executable, str(bench), "--help"],
        check=False,
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": path},
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "usage:" in done.stdout
