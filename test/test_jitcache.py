"""Where the compiled kernels are cached (pip, colcon, read-only installs)."""

from __future__ import annotations

from pathlib import Path

import numba
import pytest

from dispeval_ros import jitcache


@pytest.fixture
def numba_cache_dir(monkeypatch: pytest.MonkeyPatch) -> None:
    """Start from no NUMBA_CACHE_DIR; numba's setting is restored afterwards."""
    monkeypatch.setattr(numba.config, "CACHE_DIR", "")


def test_writable_package_keeps_numbas_choice(tmp_path: Path, numba_cache_dir: None) -> None:
    assert jitcache.ensure_cache_location(tmp_path / "core") is None
    assert numba.config.CACHE_DIR == ""
    assert (tmp_path / "core" / "__pycache__").is_dir()


def test_read_only_everywhere_falls_back_to_temporary_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, numba_cache_dir: None
) -> None:
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    monkeypatch.setattr(jitcache.tempfile, "tempdir", str(temporary))
    real = jitcache._writable
    monkeypatch.setattr(
        jitcache, "_writable", lambda folder: folder.is_relative_to(temporary) and real(folder)
    )
    chosen = jitcache.ensure_cache_location(tmp_path / "site" / "core")
    assert chosen is not None
    assert Path(chosen).parent == temporary
    assert chosen == numba.config.CACHE_DIR
    assert Path(chosen).is_dir()


def test_user_cache_is_numbas_own_fallback(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, numba_cache_dir: None
) -> None:
    """Package folder read-only but the user cache writable: numba falls back by itself."""
    package = tmp_path / "site" / "core"
    monkeypatch.setattr(jitcache, "_writable", lambda folder: package not in folder.parents)
    assert jitcache.ensure_cache_location(package) is None
    assert numba.config.CACHE_DIR == ""


def test_explicit_numba_cache_dir_wins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(jitcache, "_writable", lambda folder: False)
    assert jitcache.ensure_cache_location(tmp_path / "core") is None
    assert str(tmp_path) == numba.config.CACHE_DIR
