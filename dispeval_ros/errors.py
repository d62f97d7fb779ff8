"""Exceptions users see.

Every problem caused by the user's input (a file, an option, a topic) is a
:class:`DispevalError`. Its message is one line that names the offending input and
says what was expected and what came, so the command line can print it without a
traceback and exit with status 2.
"""

from __future__ import annotations


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
