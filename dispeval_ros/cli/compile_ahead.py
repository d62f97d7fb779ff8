"""Compile the numba kernels ahead, into the built package's cache, by running the demo once.

``setup.py`` runs :func:`compile_ahead` on the built package (``pip install .``, ``colcon
build``), so its ``__pycache__`` holds the kernels a first run needs. It lives beside the CLI it
runs, not in :mod:`dispeval_ros.jitcache` (which the kernels import), so that the cache set-up
imports nothing above ``core``.
"""

from __future__ import annotations

import contextlib
import io
import tempfile

from dispeval_ros.cli.main import main


def compile_ahead() -> None:
    """Compile (into their cache) the kernels a first run needs: the demo, run quietly once.

    The demo scores a bag offline, in robot mode and without GT, so it calls every kernel
    with the argument types of real runs; what it leaves out compiles on first use.
    """
    with tempfile.TemporaryDirectory() as out, contextlib.redirect_stdout(io.StringIO()):
        if main(["demo", "--out", out, "--json"]) != 0:
            raise SystemExit("the demo failed: kernels not compiled ahead")


if __name__ == "__main__":
    compile_ahead()
