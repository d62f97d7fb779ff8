"""The README's first-hour walkthrough runs as written (in an empty folder, no data to fetch)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def first_hour_commands() -> list[str]:
    """The shell commands of the ``first-hour`` block (continuations joined, comments dropped)."""
    text = README.read_text(encoding="utf-8")
    block = re.search(r"<!-- first-hour -->\n```bash\n(.*?)```\n<!-- /first-hour -->", text, re.S)
    assert block, "README.md has no first-hour block"
    commands, current = [], ""
    for line in block.group(1).splitlines():
        code = line.split("  #", 1)[0].rstrip() if not line.lstrip().startswith("#") else ""
        if not code.strip():
            continue
        current += code.rstrip("\\").rstrip() + " "
        if not code.endswith("\\"):
            commands.append(current.strip())
            current = ""
    return commands


def test_the_block_is_what_a_user_runs() -> None:
    commands = first_hour_commands()
    assert commands[0].startswith("pip install")
    assert all(command.startswith("dispeval ") for command in commands[1:]), commands


@pytest.mark.slow
def test_first_hour_walkthrough_runs_as_written(tmp_path: Path) -> None:
    dispeval = shutil.which("dispeval") or ""
    if not dispeval:  # the package is not installed in this environment (only importable)
        pytest.skip("the dispeval command is not on PATH (pip install . puts it there)")
    environment = {**os.environ, "PYTHONPATH": str(README.parent)}
    for command in first_hour_commands()[1:]:  # the install is what CI itself did
        done = subprocess.run(
            command,
            shell=True,
            cwd=tmp_path,
            env=environment,
            capture_output=True,
            text=True,
            check=False,
            executable="/bin/bash",
        )
        assert done.returncode == 0, f"{command}\n{done.stderr[-2000:]}"
        assert "Traceback" not in done.stderr, command
    for produced in (
        "demo/report.html",
        "results/summary.json",
        "results-lidar/results.sqlite",
        "objectives.csv",
        "results/report.html",
        "figures/curves.png",
    ):
        assert (tmp_path / produced).is_file(), produced
