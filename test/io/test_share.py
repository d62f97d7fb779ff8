"""Shared files (config, sample bag) are found wherever the package was installed."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from dispeval_ros.dds.environment import LOCALHOST_CONFIG
from dispeval_ros.io.share import shared_file_candidates


def test_shared_files_are_found_in_a_colcon_workspace(tmp_path: Path, monkeypatch: Any) -> None:
    """``--dds-config localhost`` and the sample bag resolve through the ament index too."""
    share = tmp_path / "install" / "share"
    (share / "ament_index" / "resource_index" / "packages").mkdir(parents=True)
    (share / "ament_index" / "resource_index" / "packages" / "dispeval_ros").write_text("")
    config = share / "dispeval_ros" / "config" / LOCALHOST_CONFIG
    config.parent.mkdir(parents=True)
    config.write_text("<CycloneDDS/>")
    other = tmp_path / "other"
    monkeypatch.setenv("AMENT_PREFIX_PATH", f"{other}{os.pathsep}{tmp_path / 'install'}")
    candidates = shared_file_candidates(f"config/{LOCALHOST_CONFIG}")
    assert config in candidates
    assert not any(str(c).startswith(str(other)) for c in candidates)
    assert candidates.index(config) == 1  # right after the source checkout
