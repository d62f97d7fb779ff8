"""Where the compiled kernels are cached (pip, colcon, read-only installs)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
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


REPOSITORY = Path(__file__).resolve().parents[2]
NOT_SOURCES = shutil.ignore_patterns(
    ".git", ".venv*", "build", "install", "log", "*.egg-info", "__pycache__", ".hypothesis"
)


@pytest.mark.slow
def test_the_wheel_carries_compiled_kernels_that_a_first_demo_loads(tmp_path: Path) -> None:
    """A wheel built from the repository holds the kernels the demo needs, compiled.

    Installed elsewhere (new paths and file times, as pip does), its first demo loads every
    kernel and compiles none: what a fresh ``pip install .`` gives on the machine it built on.
    """
    source = tmp_path / "source"
    shutil.copytree(REPOSITORY, source, ignore=NOT_SOURCES)
    environment = {name: value for name, value in os.environ.items() if name != "NUMBA_CACHE_DIR"}
    environment.pop("PYTHONPATH", None)
    wheels = tmp_path / "wheels"
    built = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
         "--wheel-dir", str(wheels), str(source)],
        env=environment, capture_output=True, text=True, timeout=900, check=False,
    )  # fmt: skip
    assert built.returncode == 0, built.stderr
    assert "not compiled ahead" not in built.stderr, built.stderr
    [wheel] = wheels.glob("dispeval_ros-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        cached = {Path(name).name for name in archive.namelist() if "/__pycache__/" in name}
        tops = {name.split("/")[0] for name in archive.namelist()}
    assert all(top.startswith("dispeval_ros") for top in tops), tops  # not buildtools, test
    for kernel in ("partition_cells", "accumulate_cells", "forward_warp_occlusion"):
        assert any(f".{kernel}-" in name and name.endswith(".nbi") for name in cached)
    assert any(name.endswith(".nbc") for name in cached)

    site = tmp_path / "site"
    installed = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(site),
         str(wheel)],
        env=environment, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert installed.returncode == 0, installed.stderr
    demo = subprocess.run(
        [sys.executable, "-c", "from dispeval_ros.cli.main import main; raise SystemExit(main())",
         "demo", "--out", str(tmp_path / "demo"), "--json"],
        env={**environment, "PYTHONPATH": str(site), "NUMBA_DEBUG_CACHE": "1"},
        cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert demo.returncode == 0, demo.stderr
    assert str(site) in demo.stdout  # the installed copy ran, not the source tree
    assert "data loaded" in demo.stdout
    assert "data saved" not in demo.stdout, "the first demo compiled kernels the wheel lacks"
