"""The lock that keeps a results folder to one writing run."""

from __future__ import annotations

import os
from pathlib import Path

from dispeval_ros.errors import ConfigurationError


class _FolderLock:
    """An exclusive lock on a results folder for one writing run (``flock`` on the folder).

    Two runs started at once on one folder would both create the tables (``table run already
    exists``) or meet ``database is locked``; the second is refused with one line instead. The
    lock goes with the process: a killed run leaves nothing to clean up.
    """

    def __init__(self, fd: int | None) -> None:
        self._fd = fd

    @classmethod
    def take(cls, directory: Path) -> _FolderLock:
        try:
            import fcntl
        except ImportError:  # no flock (Windows): SQLite's own locking is all there is
            return cls(None)
        fd = os.open(directory, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise ConfigurationError(
                f"{directory} is in use by another dispeval run; wait for it to end or write "
                "elsewhere"
            ) from None
        return cls(fd)

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing the descriptor releases the lock
            self._fd = None
