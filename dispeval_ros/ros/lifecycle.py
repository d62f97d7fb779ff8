"""The process life cycle of both nodes: signals, the spin loop, the orderly finish."""

from __future__ import annotations

import signal
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from typing import Any

from dispeval_ros.errors import DispevalError

SPIN_PERIOD = 0.1
"""Seconds between checks for a stop request while spinning."""
DUPLICATE_SIGNAL_WINDOW = 1.0
"""A second SIGINT sooner than this after the first is a copy, not a request to abort."""


def install_stop_handlers(stop: threading.Event) -> Callable[[], None]:
    """SIGINT / SIGTERM set ``stop`` (orderly shutdown); a later second SIGINT aborts it.

    rclpy's own handlers are not installed (``SignalHandlerOptions.NO``): they would shut the
    context down at once, so the last frames could no longer be published. Returns a function
    that restores the previous handlers. Does nothing outside the main thread.
    """
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    first: list[float] = []

    def on_sigint(signum: int, frame: object) -> None:
        # A copy of the first SIGINT (the terminal's and launch's, nearly at once) is ignored.
        if first and time.monotonic() - first[0] > DUPLICATE_SIGNAL_WINDOW:
            raise KeyboardInterrupt
        if not first:
            first.append(time.monotonic())
        stop.set()

    def on_sigterm(signum: int, frame: object) -> None:
        stop.set()

    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, on_sigint)
    signal.signal(signal.SIGTERM, on_sigterm)

    def restore() -> None:
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)

    return restore


def run_node(
    factory: Callable[[threading.Event], Any], name: str, args: Sequence[str] | None
) -> int:
    """Init rclpy, create the node, spin until a stop request, finish, tear down; exit code.

    ``factory(stop)`` builds the node; the node may set ``stop`` itself (e.g. at the end of a
    bag). After spinning, ``node.finish(executor)`` runs while the context is still valid, so
    the last results are published and every file is written; then the node is destroyed and
    rclpy shut down. A user mistake in the parameters exits with 2, after one log line.
    """
    import rclpy
    import rclpy.logging
    from rclpy.exceptions import NameValidationException, ParameterException
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(
        args=list(args) if args is not None else None,
        signal_handler_options=SignalHandlerOptions.NO,
    )
    stop = threading.Event()
    restore = install_stop_handlers(stop)
    logger = rclpy.logging.get_logger(name)
    node: Any = None
    executor: Any = None
    code = 0
    try:
        try:
            node = factory(stop)
        except (DispevalError, ParameterException, NameValidationException) as error:
            logger.fatal(str(error))
            return 2
        logger = node.get_logger()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        try:
            while not stop.is_set() and rclpy.ok():
                executor.spin_once(timeout_sec=SPIN_PERIOD)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        except Exception:  # a bug in a callback: still finish what was received
            logger.error("stopping after an unexpected error:\n" + traceback.format_exc())
            code = 1
        stop.set()
        logger.info("stopping: finishing the frames received so far")
        try:
            node.finish(executor)
        except KeyboardInterrupt:
            logger.warning("second interrupt: stopped without finishing")
            code = max(code, 130)
        code = max(code, int(getattr(node, "exit_code", 0)))
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        restore()
        rclpy.try_shutdown()
    return code
