"""Exceptions users see.

Every problem caused by the user's input (a file, an option, a topic) is a
:class:`DispevalError`. Its message is one line that names the offending input and
says what was expected and what came, so the command line can print it without a
traceback and exit with status 2.
"""

from __future__ import annotations

__all__ = [
    "CalibrationError",
    "ConfigurationError",
    "DispevalError",
    "EmptyGroundTruthError",
    "ExtrapolationError",
    "InputError",
    "LayoutError",
    "ResultsConflictError",
    "ShapeMismatchError",
    "TransformChainError",
    "TransformDataError",
]


class DispevalError(Exception):
    """Base class of all user-facing errors."""


class InputError(DispevalError):
    """A file or message cannot be read or decoded (missing, corrupt, wrong format)."""


class ShapeMismatchError(DispevalError):
    """Two maps that must be the same size are not (e.g. GT and estimate)."""


class CalibrationError(DispevalError):
    """Camera parameters are missing, unreadable or physically meaningless."""


class LayoutError(DispevalError):
    """A folder is not one of the recognised dataset layouts."""


class ConfigurationError(DispevalError):
    """An option, criterion, measure or policy name is unknown or inconsistent."""


class EmptyGroundTruthError(DispevalError):
    """A ground-truth map has no valid point, so nothing can be evaluated."""


class TransformDataError(InputError):
    """``/tf`` data that cannot be kept: two parents, a loop, too old, or none at all."""


class TransformChainError(CalibrationError):
    """No chain of transforms connects two frames (or the chain does not move the camera)."""


class ExtrapolationError(InputError):
    """A lookup at a stamp outside one ``/tf`` edge's samples (tf2's ExtrapolationException).

    ``edge`` is its ``(parent, child)``; ``future`` is True when the stamp is after the newest
    sample (waiting for more ``/tf`` may answer it; a stamp before the oldest never will be).
    """

    def __init__(
        self,
        message: str,
        *,
        edge: tuple[str, str] = ("", ""),
        stamp_ns: int = 0,
        future: bool = False,
    ) -> None:
        super().__init__(message)
        self.edge = edge
        self.stamp_ns = stamp_ns
        self.future = future


class ResultsConflictError(ConfigurationError):
    """A results folder holds results this run cannot write to.

    The message states the fact only; :meth:`advised` adds the remedy in the words of the
    front end that raised it (command-line options, ROS parameters), so no user reads an option
    of another interface.
    """

    def __init__(self, fact: str, *, resumable: bool) -> None:
        super().__init__(fact)
        self.fact = fact
        self.resumable = resumable
        """True: the folder holds results of this very run (resume continues them)."""

    def advised(self, *, resume: str, same_options: str, elsewhere: str) -> ConfigurationError:
        """The same error with its remedy: ``resume`` or ``same_options``, or ``elsewhere``."""
        remedy = resume if self.resumable else same_options
        return ConfigurationError(f"{self.fact}; {remedy} or {elsewhere}")
