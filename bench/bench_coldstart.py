"""Cold start: what a fresh install's first ``dispeval demo`` spends compiling, measured.

Each run gets an empty numba cache (``NUMBA_CACHE_DIR`` pointed at a new folder, exactly what a
fresh install sees: no ``*.nbi``/``*.nbc`` files) and is compared with a second run on the
cache the first one wrote. Prints wall and CPU seconds of both runs, their difference (the
compilation a fresh install pays once) and, with ``--breakdown``, the CPU seconds each compiled
kernel took in the cold run. Nothing is asserted. Run:

    python bench/bench_coldstart.py [--breakdown] [--read-only]

``--read-only`` also checks installs whose package folder cannot be written (a system or
read-only colcon install): the package is copied to a read-only folder and run without
``NUMBA_CACHE_DIR``, once with a writable user cache folder (numba falls back to it) and once
with a read-only home too (the kernels fall back to the temporary folder,
``dispeval_ros/jitcache.py``); each second run must be warm. As root, the runs drop the
capability that lets root write to read-only folders (``setpriv``).

``--package-root DIR`` measures another checkout (e.g. ``git archive <commit>`` unpacked) with
the same interpreter, for a before/after comparison in one session.

``--fresh-install`` measures what a user gets: ``pip install .`` of the checkout into a new
venv (the README's first command; needs the package index), then ``dispeval demo`` twice,
counting the kernels each run compiles (numba's cache log). Once as built by default (the
kernels compiled into the wheel by ``setup.py``) and once with ``DISPEVAL_COMPILE_AHEAD=0``
(compiled on first use), with the install times.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import stat
import subprocess
import sys
import tempfile
import time
import venv
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "dispeval_ros"

BREAKDOWN = r"""
import sys, tempfile, time
from collections import defaultdict
from numba.core import event
totals = defaultdict(float)
stack = []

class Timer(event.Listener):
    def on_start(self, ev):
        stack.append((time.process_time(), ev.data["dispatcher"].py_func.__qualname__))

    def on_end(self, ev):
        started, name = stack.pop()
        if not stack:  # nested compiles count in their caller
            totals[name] += time.process_time() - started

event.register("numba:compile", Timer())
from dispeval_ros.cli.main import main
try:
    main(["demo", "--out", tempfile.mkdtemp()])
except SystemExit:
    pass
for name, seconds in sorted(totals.items(), key=lambda item: -item[1]):
    print(f"    {seconds:5.2f} s  {name}", file=sys.stderr)
print(f"    {sum(totals.values()):5.2f} s  compiling in total (CPU)", file=sys.stderr)
"""


DROP_ROOT_WRITE = ["setpriv", "--bounding-set", "-dac_override,-dac_read_search,-fowner", "--"]


def run(
    code: str | None,
    env: dict[str, str],
    cwd: Path,
    prefix: list[str] | None = None,
    python: str = sys.executable,
) -> tuple[float, float, str]:
    """Wall and CPU seconds of one ``dispeval demo`` in a new process, and its stdout + stderr."""
    command = [python, "-c", code] if code else [python, "-m", "dispeval_ros"]
    command = [*(prefix or []), *command]
    if not code:
        command += ["demo", "--out", tempfile.mkdtemp(prefix="dispeval-coldstart-")]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(command, env=env, cwd=cwd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if done.returncode != 0:
        raise SystemExit(f"dispeval demo failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return wall, cpu, done.stdout + done.stderr


def cold_and_warm(
    label: str, env: dict[str, str], cwd: Path, prefix: list[str] | None = None
) -> None:
    """One cold run on an empty cache, one warm run on what it wrote."""
    cold_wall, cold_cpu, _ = run(None, env, cwd, prefix)
    warm_wall, warm_cpu, _ = run(None, env, cwd, prefix)
    print(f"\n{label}")
    print(f"  first run (empty cache)   {cold_wall:6.2f} s wall  {cold_cpu:6.2f} s CPU")
    print(f"  second run (warm cache)   {warm_wall:6.2f} s wall  {warm_cpu:6.2f} s CPU")
    print(
        f"  compilation paid once     {cold_wall - warm_wall:6.2f} s wall  "
        f"{cold_cpu - warm_cpu:6.2f} s CPU"
    )


def main() -> None:
    """Measure the cold start of ``dispeval demo``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--breakdown", action="store_true", help="CPU seconds per kernel")
    parser.add_argument("--read-only", action="store_true", help="also read-only installs")
    parser.add_argument("--package-root", type=Path, help="measure this checkout instead")
    parser.add_argument("--fresh-install", action="store_true", help="pip install into new venvs")
    args = parser.parse_args()
    base = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    # The runs start in the measured checkout: `python -m` puts the working folder first on
    # sys.path, so it decides which dispeval_ros is imported.
    checkout = PACKAGE.parent
    if args.package_root:
        checkout = args.package_root.resolve()
        base["PYTHONPATH"] = str(checkout)
        print(f"measuring the checkout in {checkout}")
    with tempfile.TemporaryDirectory(prefix="dispeval-numba-") as cache:
        cold_and_warm(
            "pip / editable install (fresh NUMBA_CACHE_DIR)",
            {**base, "NUMBA_CACHE_DIR": cache},
            checkout,
        )
    if args.breakdown:
        with tempfile.TemporaryDirectory(prefix="dispeval-numba-") as cache:
            _, _, report = run(BREAKDOWN, {**base, "NUMBA_CACHE_DIR": cache}, checkout)
        print("\nkernels compiled by the first run (CPU seconds):")
        print(report.rstrip())
    if args.read_only:
        read_only_installs(base)
    if args.fresh_install:
        fresh_installs(base, checkout)


NOT_SOURCES = shutil.ignore_patterns(
    ".git", ".venv*", "build", "install", "log", "*.egg-info", "__pycache__", ".hypothesis"
)


def fresh_installs(base: dict[str, str], checkout: Path) -> None:
    """``pip install .`` into a new venv, then two demos: kernels compiled ahead, then not."""
    for label, ahead in (("kernels compiled into the wheel (default)", "1"), ("not", "0")):
        with tempfile.TemporaryDirectory(prefix="dispeval-install-") as folder:
            root = Path(folder)
            shutil.copytree(checkout, root / "source", ignore=NOT_SOURCES)
            venv.create(root / "venv", with_pip=True)
            python = str(root / "venv" / "bin" / "python")
            env = {k: v for k, v in base.items() if k != "PYTHONPATH"}
            started = time.perf_counter()
            subprocess.run(
                [python, "-m", "pip", "install", "--quiet", str(root / "source")],
                env={**env, "DISPEVAL_COMPILE_AHEAD": ahead},
                check=True,
                capture_output=True,
            )
            installed = time.perf_counter() - started
            title = label if ahead == "1" else "DISPEVAL_COMPILE_AHEAD=0: compiled on first use"
            print(f"\nfresh install, {title}: pip install . took {installed:.1f} s")
            for run_name in ("first demo", "second demo"):
                wall, cpu, log = run(None, {**env, "NUMBA_DEBUG_CACHE": "1"}, root, python=python)
                compiled = log.count("data saved")
                print(
                    f"  {run_name:12s} {wall:6.2f} s wall  {cpu:6.2f} s CPU  "
                    f"kernels compiled: {compiled}, loaded: {log.count('data loaded')}"
                )


def read_only_installs(base: dict[str, str]) -> None:
    """A read-only copy of the package: user cache writable, then not even the home."""
    prefix = DROP_ROOT_WRITE if hasattr(os, "geteuid") and os.geteuid() == 0 else None
    with tempfile.TemporaryDirectory(prefix="dispeval-readonly-") as folder:
        root = Path(folder)
        shutil.copytree(
            PACKAGE, root / "site" / PACKAGE.name, ignore=shutil.ignore_patterns("__pycache__")
        )
        shutil.copytree(PACKAGE.parent / "bags", root / "bags")
        for sub in ("home", "tmp", "user-cache"):
            (root / sub).mkdir()
        env = {**base, "PYTHONPATH": str(root / "site"), "TMPDIR": str(root / "tmp")}
        locked = [root / "site", root / "bags", root / "home"]
        for top in locked:
            for path in [top, *top.rglob("*")]:
                path.chmod(path.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
        try:
            user_cache = {"HOME": str(root / "home"), "XDG_CACHE_HOME": str(root / "user-cache")}
            cold_and_warm(
                "read-only package, writable user cache", {**env, **user_cache}, root, prefix
            )
            print(
                f"  kernels cached in the user cache: {len(list((root / 'user-cache').rglob('*.nbi')))}"
            )
            no_home = {"HOME": str(root / "home"), "XDG_CACHE_HOME": str(root / "home" / ".cache")}
            cold_and_warm("read-only package and home", {**env, **no_home}, root, prefix)
            print(f"  kernels cached under TMPDIR: {len(list((root / 'tmp').rglob('*.nbi')))}")
        finally:
            for top in locked:
                for path in [top, *top.rglob("*")]:
                    path.chmod(path.stat().st_mode | stat.S_IWUSR)


if __name__ == "__main__":
    main()
