"""Which frame of a scene folder each estimate is scored against, and with which ground truth.

A folder may hold several frames (SceneFlow, TartanAir, a KITTI LiDAR folder), so an estimate
must say which frame it is for: a file named after its frame (``000043.png`` ↔ frame
``000043``), a folder with one file per frame, or ``--frame``. Nothing is scored against a
frame it was not named for. A LiDAR frame may also have two ground truths, the dataset's own
map (``official``) and the scan projected into the left image (``scan``); each result says
which it is against.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.files import DISPARITY_EXTENSIONS, read_disparity
from dispeval_ros.io.scenes import Scene

#: ``--gt-source`` values; ``auto`` is the official map where the frame has one, else the scan.
GT_SOURCES = ("auto", "official", "scan")
#: How each ground-truth source is named in the text output.
GT_SOURCE_TEXT = {"official": "official GT map", "scan": "projected LiDAR scan"}

Estimate = tuple[str, Path]
"""A method's name and its file (or folder of files, one per frame)."""


@dataclass(frozen=True)
class FrameTruth:
    """One frame's ground truth as scored: the map, its source and the files it came from."""

    scene: Scene
    frame: str
    source: str
    """``official`` (the dataset's GT map) or ``scan`` (a LiDAR scan projected)."""
    gt: np.ndarray
    masks: dict[str, np.ndarray] = field(default_factory=dict)
    files: tuple[Path, ...] = ()
    """The files the map was read from (the provenance hashes them)."""

    def describe(self) -> str:
        """``official GT map FILE`` or ``projected LiDAR scan FILE (calibration PATH)``."""
        text = GT_SOURCE_TEXT[self.source]
        if self.files:
            text += f" {_inside(self.files[0], self.scene.source)}"
        if self.source == "scan" and self.scene.lidar_calib is not None:
            text += f", calibration {self.scene.lidar_calib}"
        return text


def _inside(path: Path, folder: Path) -> Path:
    """``path`` relative to the scene folder when it is in it (shorter lines, same file)."""
    return path.relative_to(folder) if path.is_relative_to(folder) else path


def frame_name(scene: Scene) -> str:
    """The name a frame is chosen by: its file stem, or the folder's name for one frame."""
    return scene.frame or scene.name


def _frame_list(folder: Path, scenes: Sequence[Scene]) -> str:
    return f"the frames of {folder}: {', '.join(frame_name(s) for s in scenes)}"


def choose_frame(folder: Path, scenes: Sequence[Scene], frame: str | None) -> list[Scene]:
    """Every frame, or only the one ``frame`` names (one line listing the frames if none)."""
    if frame is None:
        return list(scenes)
    chosen = [s for s in scenes if frame_name(s) == frame]
    if not chosen:
        raise ConfigurationError(f"--frame {frame}: no such frame; {_frame_list(folder, scenes)}")
    return chosen


def frame_estimate(folder: Path, frame: str) -> Path | None:
    """The estimate of ``frame`` in a folder of estimates: ``FRAME.png`` (or .pfm, .npy, …)."""
    found = [folder / f"{frame}{ext}" for ext in DISPARITY_EXTENSIONS]
    found = [p for p in found if p.is_file()]
    if len(found) > 1:
        raise ConfigurationError(
            f"{folder}: several estimates of frame {frame} ({', '.join(p.name for p in found)})"
        )
    return found[0] if found else None


def attribute(
    folder: Path, scenes: Sequence[Scene], estimates: Sequence[Estimate], frame: str | None
) -> list[tuple[Scene, list[Estimate]]]:
    """The frames scored, each with the estimates (method, file) scored against it.

    A folder of estimates gives every frame scored its file (all frames unless ``frame``);
    a file goes to the frame its stem names, or to the one frame there is or ``--frame``
    chose. Anything else is one line naming the estimate and listing the frames.
    """
    chosen = choose_frame(folder, scenes, frame)
    by_name = {frame_name(s): s for s in scenes}
    wanted: dict[str, list[Estimate]] = {frame_name(s): [] for s in chosen}
    for method, path in estimates:
        if path.is_dir():
            missing = []
            for name, assigned in wanted.items():
                file = frame_estimate(path, name)
                if file is None:
                    missing.append(name)
                else:
                    assigned.append((method, file))
            if missing:
                raise ConfigurationError(
                    f"--est {method}={path}: no estimate of frame(s) {', '.join(missing)} in it "
                    f"(expected FRAME{'|'.join(DISPARITY_EXTENSIONS)})"
                )
            continue
        named = path.stem if path.stem in by_name else None
        if len(scenes) == 1:
            target = frame_name(scenes[0])
        elif frame is not None and named in (None, frame):
            target = frame
        elif frame is not None:
            raise ConfigurationError(
                f"--est {method}={path}: the file is named for frame {named}, but --frame "
                f"{frame} is scored"
            )
        elif named is None:
            raise ConfigurationError(
                f"--est {method}={path}: '{path.stem}' is not a frame; "
                f"{_frame_list(folder, scenes)} (name the file after its frame, give NAME=DIR "
                "with one file per frame, or choose the frame with --frame)"
            )
        else:
            target = named
        wanted.setdefault(target, []).append((method, path))
    order = [frame_name(s) for s in scenes]
    return [(by_name[name], wanted[name]) for name in order if wanted.get(name)]


def _scan_files(scene: Scene) -> tuple[Path, ...]:
    from dispeval_ros.io.lidar import RAW_CAM_TO_CAM, RAW_VELO_TO_CAM

    calib = scene.lidar_calib
    if calib is not None and calib.is_dir():
        calibs = [calib / RAW_CAM_TO_CAM, calib / RAW_VELO_TO_CAM]
    else:
        calibs = [calib] if calib is not None else []
    return tuple(p for p in (scene.lidar, *calibs) if p is not None and p.is_file())


def frame_truth(folder: Path, scene: Scene, source: str) -> FrameTruth:
    """The frame's ground truth from ``source`` (see :data:`GT_SOURCES`), or one line why not."""
    if source not in GT_SOURCES:
        raise ConfigurationError(f"--gt-source {source}: expected one of {', '.join(GT_SOURCES)}")
    name = frame_name(scene)
    has_scan = scene.lidar is not None
    official = scene.official_gt if has_scan else None
    has_official = official is not None or not has_scan
    if source == "auto":
        source = "official" if has_official else "scan"
    if source == "scan" and not has_scan:
        raise ConfigurationError(
            f"--gt-source scan: frame {name} of {folder} has no LiDAR scan ({scene.layout} "
            "scenes have their GT map only); use --gt-source official or auto"
        )
    if source == "official" and not has_official:
        raise ConfigurationError(
            f"--gt-source official: frame {name} of {folder} has no official GT map beside its "
            "scan (KITTI 2015: gt/disp_occ_0/FRAME.png); use --gt-source scan or auto"
        )
    if source == "scan" or official is None:
        files = _scan_files(scene) if source == "scan" else ()
        return FrameTruth(scene, name, source, scene.gt, dict(scene.masks), files)
    gt = read_disparity(official)
    masks = {}
    noc = official.parent.parent / "disp_noc_0" / official.name
    if noc.is_file():
        masks["nonocc"] = read_disparity(noc) > 0
    return FrameTruth(scene, name, source, gt, masks, (official,))
