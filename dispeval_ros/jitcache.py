"""Where numba keeps the compiled kernels, so a fresh install compiles them only once.

Numba caches next to the source (``__pycache__``) when the package folder is writable (pip
into a venv, ``colcon build``), else in the user's cache folder (``~/.cache/numba``: system
or read-only installs). When neither can be written (a read-only container running as a user
without a home), it would refuse to cache at all and every process would compile again; the
kernels then cache in a per-user folder under the temporary directory instead. An explicit
``NUMBA_CACHE_DIR`` always wins.

A wheel (``pip install .``) and ``colcon build`` carry the kernels compiled already:
``setup.py`` runs :func:`dispeval_ros.cli.compile_ahead.compile_ahead` (beside the CLI it
runs, so this module imports nothing of the package) on the built package, so its
``__pycache__`` holds them. numba keys them by source content, interpreter and CPU, so they load
wherever the package was built; elsewhere they compile on first use.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numba
from numba.misc.appdirs import AppDirs

PACKAGE_DIR = Path(__file__).resolve().parent


def _writable(folder: Path) -> bool:
    """Whether files can be created in ``folder`` (made if missing), as numba will try."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def ensure_cache_location(source_dir: Path = PACKAGE_DIR / "core") -> str | None:
    """Point numba at a writable cache folder when its own choices are not writable.

    Call before the kernels are decorated. Returns the folder chosen here, or ``None`` when
    numba's own locations (or ``NUMBA_CACHE_DIR``) will do.
    """
    if numba.config.CACHE_DIR:  # type: ignore[attr-defined]  # set from the environment
        return None
    user_cache = Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)
    if _writable(source_dir / "__pycache__") or _writable(user_cache):
        return None
    user = os.getuid() if hasattr(os, "getuid") else os.getlogin()
    fallback = Path(tempfile.gettempdir()) / f"dispeval-numba-{user}"
    if not _writable(fallback):
        return None  # not even the temporary folder: numba's own error says so
    numba.config.CACHE_DIR = str(fallback)  # type: ignore[attr-defined]
    return str(fallback)
