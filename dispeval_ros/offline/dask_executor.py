"""``--scheduler``: run the units of ``dispeval bag`` on a Dask distributed cluster.

``tcp://HOST:PORT`` submits to an existing scheduler (its workers must see the bag paths,
e.g. on a shared file system, and run the same dispeval version); ``local:N`` starts a local
cluster of N worker processes. Workers return a unit's rows; the driver writes them. A
worker that dies is replaced by its nanny and Dask reruns its tasks; what still fails comes
back as a failure for the driver to retry or record. A scheduler that cannot be reached or
goes away is one :class:`~dispeval_ros.errors.InputError` (the units written so far stay,
``--resume`` continues).
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import logging
import os
from collections.abc import Sequence
from concurrent.futures import CancelledError
from pathlib import Path
from typing import Any

from dispeval_ros.errors import ConfigurationError, InputError
from dispeval_ros.offline.executors import Outcome
from dispeval_ros.offline.units import Unit, UnitFailure, run_unit
from dispeval_ros.stream.core import CoreConfig

CONNECT_TIMEOUT_S = 10
WORKER_TIMEOUT_S = 60


def _require_distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise ConfigurationError(
            "--scheduler needs Dask distributed; install it with pip install 'dispeval_ros[dask]'"
        ) from None
    return distributed


SCHEMES = ("tcp",)
"""Address schemes dispeval connects with as given (no security or extra transport to set up)."""
_REFUSED_SCHEMES = {
    "tls": "needs a security configuration (certificates, keys) that dispeval does not take",
    "ucx": "needs the UCX transport (pip install distributed-ucxx), which is not installed",
    "ws": "is not tried with dispeval (its tasks run over tcp)",
    "wss": "needs a security configuration (certificates, keys) that dispeval does not take",
    "inproc": "only reaches a scheduler inside this very process",
}
"""Why each scheme distributed knows cannot be used here (ucx is used once it is installed)."""


def check_scheduler(scheduler: str) -> None:
    """``--scheduler`` names something dispeval can connect to (else one line, before any file)."""
    if local_workers(scheduler) is not None:
        return
    scheme, sep, rest = scheduler.partition("://")
    if not sep or not scheme or not rest:
        raise ConfigurationError(
            f"--scheduler expects tcp://HOST:PORT or local:N, got '{scheduler}'"
        )
    if scheme == "ucx" and importlib.util.find_spec("distributed_ucxx") is not None:
        return
    if scheme not in SCHEMES:
        why = _REFUSED_SCHEMES.get(scheme, "is not a Dask address scheme")
        raise ConfigurationError(
            f"--scheduler {scheduler}: {scheme}:// {why}; supported: "
            f"{', '.join(s + '://HOST:PORT' for s in SCHEMES)} or local:N"
        )


def local_workers(scheduler: str) -> int | None:
    """N of ``local:N`` (None for a scheduler address); a bad N is a configuration error."""
    if not scheduler.startswith("local:"):
        return None
    text = scheduler.removeprefix("local:")
    if not text.isdigit() or int(text) < 1:
        raise ConfigurationError(f"--scheduler local:N needs a worker count N ≥ 1, got '{text}'")
    return int(text)


def check_worker(paths: Sequence[str], version: str) -> str | None:
    """Run on each worker: why it cannot run the units (a bag it cannot read, another version)."""
    from dispeval_ros.version import __version__

    if __version__ != version:
        return f"runs dispeval {__version__}, the driver {version}; install the same version"
    for path in paths:
        if not os.path.exists(path):
            return f"cannot see the bag {path} (bag paths must be on a file system it shares)"
        files = [path]
        if os.path.isdir(path):
            files = [os.path.join(path, name) for name in sorted(os.listdir(path))]
        for file in files:
            try:
                with open(file, "rb") as handle:
                    handle.read(1)
            except OSError as error:
                return f"cannot read the bag {file} ({error.strerror or error})"
    return None


def connect(scheduler: str) -> tuple[Any, Any]:
    """A client of ``scheduler`` with a worker, and the local cluster it started (or None).

    ``local:N`` starts N worker processes of one thread each (the kernels use the cores). What
    fails is one :class:`~dispeval_ros.errors.InputError`: no cluster, no scheduler, no worker.
    """
    check_scheduler(scheduler)
    distributed = _require_distributed()
    cluster = None
    count = local_workers(scheduler)
    logging.getLogger("distributed").setLevel(logging.CRITICAL)  # errors here are one line
    if count is not None:
        try:
            cluster = distributed.LocalCluster(
                n_workers=count,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.CRITICAL,
            )
        except (OSError, RuntimeError, TimeoutError) as error:
            raise InputError(
                f"cannot start a local Dask cluster of {count} workers ({_one_line(error)}); "
                "a script that runs it needs an if __name__ == '__main__' guard"
            ) from None
        client = distributed.Client(cluster)
    else:
        try:
            client = distributed.Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError, TypeError) as error:
            raise InputError(
                f"cannot reach the Dask scheduler at {scheduler} ({_one_line(error)})"
            ) from None
    try:
        client.wait_for_workers(1, timeout=WORKER_TIMEOUT_S)
    except (OSError, TimeoutError) as error:
        disconnect(client, cluster)
        raise InputError(
            f"the Dask scheduler at {scheduler} has no worker ({_one_line(error)})"
        ) from None
    return client, cluster


def disconnect(client: Any, cluster: Any) -> None:
    """Close a client of :func:`connect` and the local cluster it started (errors ignored)."""
    for part in (client, cluster):
        if part is not None:
            with contextlib.suppress(Exception):
                part.close()


class DaskExecutor:
    """Units as Dask tasks, one thread per worker process (the kernels use the cores)."""

    def __init__(self, config: CoreConfig, scheduler: str) -> None:
        self.config = config
        self.scheduler = scheduler
        self._running: dict[Any, tuple[int, Unit]] = {}
        self._client, self._cluster = connect(scheduler)
        self.workers = max(1, len(self._client.scheduler_info().get("workers", {})))

    @property
    def client(self) -> Any:
        """The Dask client (to inspect or drive the cluster)."""
        return self._client

    def start(self, paths: Sequence[Path]) -> None:
        """Nothing to start: the cluster's workers are running."""

    def check(self, paths: Sequence[Path]) -> None:
        """Every worker reads every bag and runs this dispeval version (else one line)."""
        from dispeval_ros import __version__

        wanted = [str(Path(path).absolute()) for path in paths]
        try:
            answers = self._client.run(check_worker, wanted, __version__, on_error="return")
        except (OSError, TimeoutError) as error:
            raise self._gone(error) from None
        for worker, answer in sorted(answers.items()):
            if isinstance(answer, BaseException):
                raise InputError(
                    f"Dask worker {worker} cannot run dispeval ({_one_line(answer)}); "
                    "install dispeval_ros[dask] there"
                )
            if answer is not None:
                raise InputError(f"Dask worker {worker} {answer}")

    def submit(self, index: int, unit: Unit) -> None:
        """Submit ``unit`` as a task (not pure: a retry must run again)."""
        # workers resolve relative paths against their own folder: send absolute ones
        task = dataclasses.replace(unit, path=unit.path.absolute())
        try:
            future = self._client.submit(run_unit, self.config, task, pure=False)
        except (OSError, TimeoutError, RuntimeError) as error:
            raise self._gone(error) from None
        self._running[future] = (index, unit)

    def completed(self) -> list[Outcome]:
        """The tasks finished by now (at least one); a lost scheduler raises."""
        distributed = _require_distributed()
        try:
            done, _ = distributed.wait(list(self._running), return_when="FIRST_COMPLETED")
        except (OSError, TimeoutError, CancelledError) as error:  # cancelled: scheduler gone
            raise self._gone(error) from None
        outcomes: list[Outcome] = []
        for future in done:
            index, unit = self._running.pop(future)
            if future.status == "finished":
                result = future.result()
                outcomes.append((index, dataclasses.replace(result, unit=unit)))
            elif future.status == "error":
                raised = future.exception()
                outcomes.append((index, UnitFailure(unit, _task_error(raised))))
            elif future.status == "cancelled":  # the client lost the scheduler
                raise self._gone(None)
            else:  # "lost": its result died with its worker before it got here
                future.release()
                outcomes.append((index, UnitFailure(unit, "its result was lost with its worker")))
        return outcomes

    def _gone(self, error: BaseException | None) -> InputError:
        why = f" ({_one_line(error)})" if error is not None else ""
        return InputError(
            f"lost the Dask scheduler at {self.scheduler}{why}; the units written so far are "
            "kept, continue with --resume"
        )

    def close(self) -> None:
        """Close the client (and the local cluster this executor started)."""
        disconnect(self._client, self._cluster)
        self._running.clear()


def _task_error(error: BaseException | None) -> str:
    if error is not None and type(error).__name__ == "KilledWorker":
        return "its worker died every time it ran it"
    return _one_line(error) if error is not None else "unknown error"


def _one_line(error: BaseException) -> str:
    text = " ".join(str(error).split())
    return f"{type(error).__name__}: {text}" if text else type(error).__name__
