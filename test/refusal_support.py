"""What the refusal tests share: a refusal is one line, exit 2, and leaves the folder as it was."""

from __future__ import annotations

from pathlib import Path


def assert_refused(code: int, err: str, *needles: str) -> None:
    """Exit 2, one line on stderr naming ``needles``, no traceback."""
    assert code == 2, err
    assert err.count("\n") == 1, err
    assert "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (hidden ones too) with its bytes: 'left as it was' is equality."""
    return {
        str(path.relative_to(folder)): path.read_bytes()
        for path in sorted(folder.rglob("*"))
        if path.is_file()
    } | {str(path.relative_to(folder)) + "/": b"" for path in folder.rglob("*") if path.is_dir()}
