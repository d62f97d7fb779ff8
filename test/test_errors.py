"""Every error class of ``dispeval_ros.errors``: a DispevalError, exported, exit status 2.

The classes are read from the module itself, not listed here, so a class added there is
checked without editing this file.
"""

from __future__ import annotations

import argparse
import inspect

import pytest

import dispeval_ros
from dispeval_ros import errors
from dispeval_ros.cli import main as cli_main
from dispeval_ros.errors import DispevalError, ResultsConflictError

ERROR_CLASSES = sorted(
    (kind for kind in vars(errors).values() if inspect.isclass(kind)),
    key=lambda kind: kind.__name__,
)
"""Every class the errors module holds (it imports none: each is defined there)."""


def make(kind: type[DispevalError]) -> DispevalError:
    """An instance with a one-line message (ResultsConflictError also says if it resumes)."""
    if issubclass(kind, ResultsConflictError):
        return kind("results of another run", resumable=False)
    return kind("a one-line message")


def test_the_module_defines_the_classes_it_holds() -> None:
    assert [kind.__module__ for kind in ERROR_CLASSES] == [errors.__name__] * len(ERROR_CLASSES)
    assert len(ERROR_CLASSES) >= 8  # DispevalError and its seven kinds today


@pytest.mark.parametrize("kind", ERROR_CLASSES, ids=lambda kind: kind.__name__)
def test_every_error_is_a_dispeval_error(kind: type) -> None:
    assert issubclass(kind, DispevalError)
    assert issubclass(DispevalError, Exception)


@pytest.mark.parametrize("kind", ERROR_CLASSES, ids=lambda kind: kind.__name__)
def test_every_error_is_exported(kind: type) -> None:
    """``from dispeval_ros.errors import *`` gives it (its ``__all__``, when it has one)."""
    exported = getattr(errors, "__all__", [n for n in vars(errors) if not n.startswith("_")])
    assert kind.__name__ in exported
    assert "DispevalError" in dispeval_ros.__all__


@pytest.mark.parametrize("kind", ERROR_CLASSES, ids=lambda kind: kind.__name__)
def test_every_error_exits_the_cli_with_status_2_and_one_line(
    kind: type[DispevalError], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def run(args: argparse.Namespace) -> int:
        raise make(kind)

    parser = argparse.ArgumentParser()
    parser.set_defaults(command="demo", run=run)
    monkeypatch.setattr(cli_main, "build_parser", lambda: parser)
    assert cli_main.main([]) == 2
    printed = capsys.readouterr().err
    assert printed.startswith("dispeval demo: error: ")
    assert printed.count("\n") == 1
