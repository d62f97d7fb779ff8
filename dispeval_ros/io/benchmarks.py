"""Benchmark dataset trees and result folders laid out as each official tool expects.

:func:`discover` lists the frames of a ground-truth tree for a protocol:

- MiddEval3 (``trainingQ/F/H``) and ETH3D two-view: one folder per scene with
  ``disp0GT.pfm`` (ETH3D also ``disp0.pfm``), ``mask0nocc.png``, ``calib.txt``;
- KITTI 2015: ``disp_occ_0/NNNNNN_10.png`` with ``disp_noc_0/`` and ``obj_map/`` beside it,
  found in the folder, its ``training/`` or its ``gt/`` (the kitti-lidar layout);
- KITTI 2012: ``disp_occ/`` with ``disp_noc/`` beside it (same places);
- any single scene folder :func:`dispeval_ros.io.load_scene` recognises.

:func:`find_estimate` finds a method's result for a frame where the protocol's
:class:`~dispeval_ros.core.protocols.ResultLayout` says its tool takes it (``disp0NAME.pfm``
in a MiddEval3 scene folder, ``DIR/disp_0/NNNNNN_10.png`` for KITTI, ...).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dispeval_ros.core.protocols import FrameData, Protocol
from dispeval_ros.errors import ConfigurationError, InputError, LayoutError
from dispeval_ros.io.files import read_disparity, read_mask
from dispeval_ros.io.scenes import load_scene

_NDISP = re.compile(r"(?m)^\s*ndisp\s*=\s*([0-9.]+)")
#: GT folder pairs (all pixels, non-occluded) per protocol, in order of preference: KITTI 2012
#: metrics may also be computed on a KITTI 2015 tree.
_KITTI_GT = {
    "kitti2015": (("disp_occ_0", "disp_noc_0"),),
    "kitti2012": (("disp_occ", "disp_noc"), ("disp_occ_0", "disp_noc_0")),
}


@dataclass(frozen=True)
class BenchmarkFrame:
    """The files of one frame of a benchmark tree (``None``: the tree has no such file)."""

    name: str
    folder: Path
    gt: Path
    gt_noc: Path | None = None
    mask: Path | None = None
    obj_map: Path | None = None
    calib: Path | None = None
    single: bool = False

    def files(self) -> dict[str, Path]:
        """The ground-truth side files by role (for the provenance record)."""
        roles = {
            "gt": self.gt,
            "gt_noc": self.gt_noc,
            "mask": self.mask,
            "obj_map": self.obj_map,
            "calib": self.calib,
        }
        return {role: path for role, path in roles.items() if path is not None}


def _file(path: Path) -> Path | None:
    return path if path.is_file() else None


def _scene_frame(folder: Path) -> BenchmarkFrame | None:
    gt = _file(folder / "disp0GT.pfm") or _file(folder / "disp0.pfm")
    if gt is None:
        return None
    return BenchmarkFrame(
        name=folder.name,
        folder=folder,
        gt=gt,
        mask=_file(folder / "mask0nocc.png"),
        calib=_file(folder / "calib.txt"),
    )


def _refuse_scene_without_gt(protocol: Protocol, folders: list[Path]) -> None:
    """A scene folder (it holds ``im0.png``) beside the others but without GT: refused.

    Leaving it out would change the weighted / mean table without a word, and the official
    table needs every scene: the user removes the folder or adds its GT.
    """
    for folder in folders:
        if (folder / "im0.png").is_file():
            raise LayoutError(
                f"{folder}: a {protocol.title} scene folder without disp0GT.pfm (or disp0.pfm); "
                "the table over the scenes needs every scene's ground truth: add it or move the "
                "folder out of the tree"
            )


def _kitti_root(root: Path, occ: str) -> Path | None:
    for candidate in (root, root / "training", root / "gt", root / "training" / "gt"):
        if (candidate / occ).is_dir():
            return candidate
    return None


def _kitti_frames(root: Path, protocol: str) -> list[BenchmarkFrame]:
    for occ, noc in _KITTI_GT[protocol]:
        base = _kitti_root(root, occ)
        if base is not None:
            return _kitti_tree(base, occ, noc, protocol)
    return []


def _kitti_tree(base: Path, occ: str, noc: str, protocol: str) -> list[BenchmarkFrame]:
    frames = []
    for gt in sorted(p for p in (base / occ).iterdir() if p.suffix.lower() == ".png"):
        frames.append(
            BenchmarkFrame(
                name=gt.stem,
                folder=base,
                gt=gt,
                gt_noc=_file(base / noc / gt.name),
                obj_map=_file(base / "obj_map" / gt.name) if protocol == "kitti2015" else None,
            )
        )
    return frames


def _single_scene(root: Path) -> list[BenchmarkFrame]:
    scene = load_scene(root)  # raises a one-line LayoutError for unknown folders
    gt = next(
        (
            p
            for p in sorted(root.iterdir())
            if p.is_file()
            and (
                p.name.lower() in ("disp0gt.pfm", "disp0.pfm", "gt_disparity.png", "disp_gt.png")
                or p.name.lower().startswith("disp_occ")
            )
        ),
        None,
    )
    if gt is None:
        raise LayoutError(
            f"{root}: a {scene.layout} scene, but no protocol ground-truth file in it "
            "(disp0GT.pfm, disp0.pfm, gt_disparity.png, disp_gt.png or disp_occ*.png)"
        )
    noc = _file(root / gt.name.replace("disp_occ", "disp_noc")) if "disp_occ" in gt.name else None
    return [
        BenchmarkFrame(
            name=root.name,
            folder=root,
            gt=gt,
            gt_noc=noc,
            mask=_file(root / "mask0nocc.png"),
            obj_map=_file(root / "obj_map.png"),
            calib=_file(root / "calib.txt"),
            single=True,
        )
    ]


def discover(protocol: Protocol, root: Path) -> list[BenchmarkFrame]:
    """Every frame of the ground-truth tree ``root`` for ``protocol``, in name order."""
    root = Path(root)
    if not root.is_dir():
        raise InputError(
            f"{root}: dataset folder not found"
            if not root.exists()
            else f"{root}: expected a dataset folder, got a file"
        )
    if protocol.name in _KITTI_GT:
        frames = _kitti_frames(root, protocol.name)
        if frames:
            return frames
    else:
        own = _scene_frame(root)
        if own is not None:
            return [own]
        folders = [p for p in sorted(root.iterdir()) if p.is_dir()]
        found = {p: _scene_frame(p) for p in folders}
        scenes = [frame for frame in found.values() if frame is not None]
        if scenes:
            _refuse_scene_without_gt(protocol, [p for p, f in found.items() if f is None])
            return scenes
    try:
        return _single_scene(root)
    except LayoutError:
        expected = {
            "middeval3": "scene folders with disp0GT.pfm (MiddEval3 trainingQ/H/F)",
            "eth3d": "scene folders with disp0GT.pfm or disp0.pfm (ETH3D two-view)",
            "kitti2015": "disp_occ_0/ (in the folder, training/ or gt/)",
            "kitti2012": "disp_occ/ or disp_occ_0/ (in the folder, training/ or gt/)",
        }[protocol.name]
        raise LayoutError(f"{root}: not a {protocol.title} tree; expected {expected}") from None


def estimate_candidates(
    protocol: Protocol, frame: BenchmarkFrame, method: str, results: Path | None
) -> list[Path]:
    """Where ``protocol``'s tool takes a method's result for ``frame`` (its :class:`ResultLayout`)."""
    if results is not None and results.is_file():
        return [results]
    base = frame.folder if results is None else results
    return [base / path for path in protocol.results.paths(results is not None, frame.name, method)]


def find_estimate(
    protocol: Protocol, frame: BenchmarkFrame, method: str, results: Path | None
) -> Path:
    """The one result file of ``method`` for ``frame``, or a one-line error naming every place.

    Only the protocol's own layouts are looked at, so a file the tool would refuse is never
    picked; two files that both fit are refused by name rather than one chosen silently.
    """
    layout = protocol.results
    candidates = estimate_candidates(protocol, frame, method, results)
    if not candidates:
        raise ConfigurationError(
            f"--est {method}: {protocol.title} results are not kept in the dataset tree; give "
            f"--est {method}=RESULTS ({layout.describe().replace('`', '')})"
        )
    found = [candidate for candidate in candidates if candidate.is_file()]
    if len(found) > 1:
        raise InputError(
            f"method '{method}', frame {frame.name}: {len(found)} result files fit the "
            f"{protocol.title} layouts ({', '.join(str(f) for f in found)}); keep one"
        )
    if found:
        return found[0]
    others = [
        str(other)
        for candidate in candidates
        for other in (candidate.with_suffix(s) for s in (".pfm", ".png", ".npy"))
        if other != candidate and other.is_file()
    ]
    beside = f"; found {', '.join(others)}, not read" if others else ""
    raise InputError(
        f"no result of method '{method}' for frame {frame.name}: looked for "
        f"{', '.join(str(c) for c in candidates)} ({protocol.title} results: "
        f"{layout.encoding_text()}){beside}"
    )


def _ndisp(calib: Path | None) -> float | None:
    if calib is None:
        return None
    try:
        found = _NDISP.search(calib.read_text(encoding="utf-8", errors="replace"))
    except OSError as error:
        raise InputError(f"{calib}: cannot read ({error.strerror or error})") from None
    return float(found.group(1)) if found else None


def load_frame(frame: BenchmarkFrame) -> FrameData:
    """Read a frame's ground-truth side (GT, noc GT, mask values, object map, ndisp)."""
    gt = read_disparity(frame.gt)
    return FrameData(
        frame=frame.name,
        gt=gt,
        gt_noc=None if frame.gt_noc is None else read_disparity(frame.gt_noc),
        nonocc_mask=None if frame.mask is None else read_mask(frame.mask),
        obj_map=None if frame.obj_map is None else read_mask(frame.obj_map),
        ndisp=_ndisp(frame.calib),
    )


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _png_format(path: Path) -> tuple[int, int] | None:
    """(bit depth, colour type) from a PNG's IHDR, or None when the file is not a PNG."""
    try:
        with path.open("rb") as file:
            head = file.read(26)
    except OSError as error:
        raise InputError(f"{path}: cannot read ({error.strerror or error})") from None
    if len(head) < 26 or not head.startswith(_PNG_SIGNATURE):
        return None
    return head[24], head[25]


def read_estimate(path: Path, protocol: Protocol | None = None) -> np.ndarray:
    """A result file as float32 pixels, in the format the benchmark's tool reads.

    KITTI results must be 1-channel 16-bit PNGs (value = disparity × 256, 0 = no estimate),
    MiddEval3 and ETH3D results PFM files (``INF`` = no estimate): the official tools refuse
    anything else, and another encoding would change what counts as missing.
    """
    if protocol is not None:
        layout = protocol.results
        fits = (
            _png_format(path) == (16, 0)
            if layout.encoding == "png16"
            else path.suffix.lower() == ".pfm"
        )
        if not fits:
            raise InputError(
                f"{path}: {protocol.title} results must be {layout.encoding_text()}, as "
                f"{protocol.tool} reads them"
            )
    return read_disparity(path)
