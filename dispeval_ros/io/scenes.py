"""Scene folders of the public stereo benchmarks, recognised by their files.

:func:`load_scene` turns a folder into a :class:`Scene`: the left ground truth in pixels
(invalid points kept as the source encodes them: ``inf`` or ``0``), the right ground truth
when published, the official masks as boolean arrays, the camera and the image paths.
:func:`list_frames` returns every frame of a sequence folder (SceneFlow, TartanAir).
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import cv2
import numpy as np

from dispeval_ros.core.camera import Camera
from dispeval_ros.core.masks import inside_mask
from dispeval_ros.errors import CalibrationError, InputError, LayoutError, ShapeMismatchError
from dispeval_ros.io.calib import read_calib
from dispeval_ros.io.files import PathLike, read_disparity, read_mask

#: The layouts :func:`load_scene` recognises.
LAYOUTS = (
    "middlebury2001",
    "middeval3",
    "kitti",
    "eth3d",
    "sceneflow",
    "tartanair",
    "motorcycle-npz",
    "kitti-lidar",
)

#: The Motorcycle npz of scikit-image ships no calibration; its documentation gives these
#: (Middlebury 2014 Motorcycle, quarter size 741×500): f and doffs in px, baseline in mm.
MOTORCYCLE_NPZ = "motorcycle_disp.npz"
MOTORCYCLE_F = 994.978
MOTORCYCLE_DOFFS = 31.086
MOTORCYCLE_BASELINE_MM = 193.001

_FRAME_PFM = re.compile(r"^\d+\.pfm$", re.IGNORECASE)
_TARTANAIR_SUFFIX = "_left_disp.npy"
_KITTI_P = re.compile(r"(?m)^\s*(P_rect_0[23]|P[23])\s*:")


@dataclass(eq=False)
class Scene:
    """One stereo frame with its ground truth.

    ``gt``/``gt_right`` are float32 disparities in pixels (left / right view); invalid points
    keep the source's encoding (``inf`` or ``0``). ``masks`` holds the official masks as
    boolean arrays keyed ``"all"``, ``"nonocc"``, ``"disc"`` (whichever the source
    publishes). ``camera`` is ``None`` when the source has no calibration.
    """

    name: str
    layout: str
    gt: np.ndarray
    gt_right: np.ndarray | None
    masks: dict[str, np.ndarray]
    camera: Camera | None
    left: Path | None
    right: Path | None
    source: Path
    lidar: Path | None = None
    """LiDAR scenes: the raw scan the GT was projected from."""
    lidar_calib: Path | None = None
    """LiDAR scenes: the calibration (a file or a raw-calibration folder)."""
    frame: str | None = None
    """A frame of a multi-frame folder: the file stem its files share (``None``: one frame)."""
    official_gt: Path | None = None
    """LiDAR scenes: the dataset's own GT map of the same frame, where published (KITTI 2015)."""


# ----------------------------------------------------------------------------------- helpers


def _existing(folder: Path, *names: str) -> Path | None:
    """Return the first of ``names`` that is a file in ``folder`` (exact name, then any case)."""
    for name in names:
        candidate = folder / name
        if candidate.is_file():
            return candidate
    lowered = {entry.name.lower(): entry for entry in folder.iterdir() if entry.is_file()}
    for name in names:
        if name.lower() in lowered:
            return lowered[name.lower()]
    return None


def _same_shape(gt: np.ndarray, gt_file: Path, other: np.ndarray, other_file: Path) -> None:
    if other.shape[:2] != gt.shape[:2]:
        raise ShapeMismatchError(
            f"{other_file}: expected the size of {gt_file.name} "
            f"({gt.shape[1]}×{gt.shape[0]}), found {other.shape[1]}×{other.shape[0]}"
        )


def _mask(file: Path, gt: np.ndarray, gt_file: Path) -> np.ndarray:
    """Boolean mask of an official mask image, by the one rule (255 inside, 128/0 outside)."""
    raw = read_mask(file)
    _same_shape(gt, gt_file, raw, file)
    return inside_mask(str(file), raw)


def _required_calib(folder: Path, *names: str) -> Camera:
    calib = _existing(folder, *names)
    if calib is None:
        raise CalibrationError(
            f"{folder / names[0]}: calibration file missing (the scene's layout needs it)"
        )
    return read_calib(calib)


def _files_preview(folder: Path, limit: int = 8) -> str:
    names = sorted(entry.name + ("/" if entry.is_dir() else "") for entry in folder.iterdir())
    if not names:
        return "nothing (empty folder)"
    shown = ", ".join(names[:limit])
    return shown + (f", ... ({len(names)} entries)" if len(names) > limit else "")


# ---------------------------------------------------------------------------------- layouts


def _load_middlebury2001(folder: Path) -> Scene:
    gt_file = folder / "groundtruth.png"
    info = folder / "info.txt"
    try:
        lines = info.read_text(encoding="utf-8", errors="replace").split()
    except OSError as exc:
        raise InputError(f"{info}: cannot read ({exc.strerror or exc})") from None
    first = lines[0] if lines else ""
    try:
        scale = float(first)
    except ValueError:
        scale = math.nan
    if not math.isfinite(scale) or scale <= 0:
        raise InputError(
            f"{info}: expected the GT scale (a number > 0) as the first value, got {first!r}"
        )
    gt = read_disparity(gt_file, scale=scale)
    right_file = _existing(folder, "groundtruth_right.png", "groundtruth_right.pgm")
    gt_right = None
    if right_file is not None:
        gt_right = read_disparity(right_file, scale=scale)
        _same_shape(gt, gt_file, gt_right, right_file)
    masks: dict[str, np.ndarray] = {}
    for name in ("all", "nonocc", "disc"):
        mask_file = _existing(folder, f"{name}.png")
        if mask_file is not None:
            # 255 = in the mask; disc.png also marks other non-occluded points with 128.
            masks[name] = _mask(mask_file, gt, gt_file)
    return Scene(
        name=folder.name,
        layout="middlebury2001",
        gt=gt,
        gt_right=gt_right,
        masks=masks,
        camera=None,
        left=_existing(folder, "imL.png", "im2.png", "view1.png"),
        right=_existing(folder, "imR.png", "im6.png", "view5.png"),
        source=folder,
    )


def _load_middlebury2014(folder: Path, layout: str, gt_name: str) -> Scene:
    """MiddEval3 (``disp0GT.pfm``) and ETH3D two-view (``disp0.pfm``) folders."""
    gt_file = folder / gt_name
    camera = _required_calib(folder, "calib.txt")
    gt = read_disparity(gt_file)
    right_name = gt_name.replace("0", "1", 1)
    right_file = _existing(folder, right_name)
    gt_right = None
    if right_file is not None:
        gt_right = read_disparity(right_file)
        _same_shape(gt, gt_file, gt_right, right_file)
    masks: dict[str, np.ndarray] = {}
    mask_file = _existing(folder, "mask0nocc.png")
    if mask_file is not None:
        # 255 = non-occluded, 128 = occluded, 0 = no GT.
        masks["nonocc"] = _mask(mask_file, gt, gt_file)
    return Scene(
        name=folder.name,
        layout=layout,
        gt=gt,
        gt_right=gt_right,
        masks=masks,
        camera=camera,
        left=_existing(folder, "im0.png"),
        right=_existing(folder, "im1.png"),
        source=folder,
    )


def _kitti_gt(folder: Path) -> Path | None:
    found = _existing(folder, "gt_disparity.png", "disp_gt.png")
    if found is not None:
        return found
    occ = sorted(
        entry
        for entry in folder.iterdir()
        if entry.is_file()
        and entry.name.lower().startswith("disp_occ")
        and entry.suffix.lower() == ".png"
    )
    return occ[0] if occ else None


def _kitti_calib_file(folder: Path) -> Path | None:
    """Find the first ``calib*.txt`` holding rectified projection matrices (P_rect_02 or P2)."""
    for entry in sorted(folder.iterdir()):
        if not (
            entry.is_file()
            and entry.name.lower().startswith("calib")
            and entry.suffix.lower() == ".txt"
        ):
            continue
        try:
            text = entry.read_text(encoding="utf-8", errors="replace")
        except OSError:
            continue
        if _KITTI_P.search(text):
            return entry
    return None


def _load_kitti(folder: Path, gt_file: Path) -> Scene:
    gt = read_disparity(gt_file)
    masks: dict[str, np.ndarray] = {}
    lower = gt_file.name.lower()
    if lower.startswith("disp_occ"):
        noc_name = "disp_noc" + gt_file.name[len("disp_occ") :]
        noc_file = _existing(folder, noc_name)
        if noc_file is not None:
            noc = read_disparity(noc_file)
            _same_shape(gt, gt_file, noc, noc_file)
            masks["nonocc"] = noc > 0
    camera = None
    calib_file = _kitti_calib_file(folder)
    q_file = _existing(folder, "Q.dat")
    if calib_file is not None:
        camera = read_calib(calib_file)
    elif q_file is not None:
        camera = read_calib(q_file)
    return Scene(
        name=folder.name,
        layout="kitti",
        gt=gt,
        gt_right=None,
        masks=masks,
        camera=camera,
        left=_existing(
            folder, "stereo_left.png", "image_2.png", "image.png", "left.png", "im0.png"
        ),
        right=_existing(folder, "stereo_right.png", "image_3.png", "right.png", "im1.png"),
        source=folder,
    )


def _load_motorcycle_npz(folder: Path) -> Scene:
    camera = Camera(
        f=MOTORCYCLE_F,
        baseline=MOTORCYCLE_BASELINE_MM / 1000.0,
        doffs=MOTORCYCLE_DOFFS,
    )
    return Scene(
        name=folder.name,
        layout="motorcycle-npz",
        gt=read_disparity(folder / MOTORCYCLE_NPZ),
        gt_right=None,
        masks={},
        camera=camera,
        left=_existing(folder, "motorcycle_left.png"),
        right=_existing(folder, "motorcycle_right.png"),
        source=folder,
    )


def _sceneflow_frames(folder: Path) -> list[str]:
    disparity = folder / "Disparity"
    if not disparity.is_dir():
        return []
    return sorted(
        entry.stem
        for entry in disparity.iterdir()
        if entry.is_file() and _FRAME_PFM.match(entry.name)
    )


def _sceneflow_camera(folder: Path) -> Camera:
    q_file = _existing(folder / "Disparity", "Q.dat") or _existing(folder, "Q.dat")
    if q_file is None:
        raise CalibrationError(
            f"{folder / 'Disparity' / 'Q.dat'}: calibration file missing (SceneFlow needs "
            f"the Q reprojection matrix)"
        )
    # FlyingThings3D's baseline is 1 Blender unit: depths are in scene units, not metres.
    return dataclasses.replace(read_calib(q_file), unit="scene")


def _sceneflow_frame(folder: Path, frame: str, camera: Camera) -> Scene:
    images = [folder / side / f"{frame}.png" for side in ("Left", "Right")]
    return Scene(
        name=f"{folder.name}_{frame}",
        layout="sceneflow",
        frame=frame,
        gt=read_disparity(folder / "Disparity" / f"{frame}.pfm"),
        gt_right=None,
        masks={},
        camera=camera,
        left=images[0] if images[0].is_file() else None,
        right=images[1] if images[1].is_file() else None,
        source=folder,
    )


def _tartanair_frames(folder: Path) -> list[str]:
    return sorted(
        entry.name[: -len(_TARTANAIR_SUFFIX)]
        for entry in folder.iterdir()
        if entry.is_file() and entry.name.endswith(_TARTANAIR_SUFFIX)
    )


def _tartanair_frame(folder: Path, frame: str, camera: Camera) -> Scene:
    gt = read_disparity(folder / f"{frame}{_TARTANAIR_SUFFIX}")
    right_file = _existing(folder, f"{frame}_right_disp.npy")
    gt_right = None
    if right_file is not None:
        gt_right = read_disparity(right_file)
        _same_shape(gt, folder / f"{frame}{_TARTANAIR_SUFFIX}", gt_right, right_file)
    return Scene(
        name=f"{folder.name}_{frame}",
        layout="tartanair",
        frame=frame,
        gt=gt,
        gt_right=gt_right,
        masks={},
        camera=camera,
        left=_existing(folder, f"{frame}_left.png"),
        right=_existing(folder, f"{frame}_right.png"),
        source=folder,
    )


def _image_size(file: Path) -> tuple[int, int]:
    """(rows, columns) of an image file (a LiDAR scene's GT takes the left image's size)."""
    image = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise InputError(f"{file}: cannot read the left image (expected a PNG or other image)")
    return int(image.shape[0]), int(image.shape[1])


def _lidar_frame(
    folder: Path,
    name: str,
    scan: Path,
    left: Path,
    right: Path | None,
    calib: Path,
    frame: str | None = None,
) -> Scene:
    """A frame whose GT is a LiDAR scan projected into the left image (default filter)."""
    # Imported here: the LiDAR readers need the projection kernel, other layouts do not.
    from dispeval_ros.core.projection import project_cloud
    from dispeval_ros.io.lidar import read_lidar_calib, read_velodyne_bin

    calibration = read_lidar_calib(calib)
    camera = calibration.camera
    projected = project_cloud(
        read_velodyne_bin(scan), calibration.matrix, _image_size(left), camera
    )
    return Scene(
        name=name,
        layout="kitti-lidar",
        gt=projected.disparity,
        gt_right=None,
        masks={},
        camera=camera,
        left=left,
        right=right,
        source=folder,
        lidar=scan,
        lidar_calib=calib,
        frame=frame,
        official_gt=None if frame is None else _official_lidar_gt(folder, frame),
    )


def _official_lidar_gt(folder: Path, frame: str) -> Path | None:
    """The KITTI 2015 GT map published beside a frame's scan (``gt/disp_occ_0/FRAME.png``)."""
    for base in (folder / "gt", folder):
        candidate = base / "disp_occ_0" / f"{frame}.png"
        if candidate.is_file():
            return candidate
    return None


def _lidar_calib_location(folder: Path) -> Path | None:
    """KITTI LiDAR calibration for ``folder``, looked for in order.

    An object-format ``calib*.txt`` with ``Tr_velo_to_cam`` in it, else the folder holding the
    raw ``calib_velo_to_cam.txt`` + ``calib_cam_to_cam.txt``: the folder, its parent (KITTI raw's
    day folder) or a sibling folder.
    """
    from dispeval_ros.io.lidar import RAW_VELO_TO_CAM

    for entry in sorted(folder.glob("calib*.txt")):
        try:
            if "Tr_velo_to_cam" in entry.read_text(encoding="utf-8", errors="replace"):
                return entry
        except OSError:
            continue
    candidates = [folder, folder.parent]
    candidates += sorted(p for p in folder.parent.iterdir() if p.is_dir() and p != folder)
    return next((c for c in candidates if (c / RAW_VELO_TO_CAM).is_file()), None)


def _lidar_frames(folder: Path) -> list[Callable[[], Scene]]:
    """Frames of a KITTI LiDAR folder (none when it has no scan).

    ``lidar.bin`` + ``left.png`` (one frame), or ``velodyne_points/NNNNNN.bin`` +
    ``image_02/NNNNNN.png`` (one frame per scan).
    """
    single = _existing(folder, "lidar.bin")
    scans = sorted((folder / "velodyne_points").glob("*.bin")) if single is None else [single]
    if not scans:
        return []
    calib = _lidar_calib_location(folder)
    if calib is None:
        raise CalibrationError(
            f"{folder}: LiDAR scans found but no calibration: expected a calib*.txt with "
            f"Tr_velo_to_cam, or calib_velo_to_cam.txt + calib_cam_to_cam.txt in the folder, "
            f"its parent or a sibling folder"
        )
    loaders: list[Callable[[], Scene]] = []
    for scan in scans:
        if single is not None:
            left, right, name = (
                _existing(folder, "left.png"),
                _existing(folder, "right.png"),
                folder.name,
            )
        else:
            left = folder / "image_02" / f"{scan.stem}.png"
            right_file = folder / "image_03" / f"{scan.stem}.png"
            right, name = (
                (right_file if right_file.is_file() else None),
                f"{folder.name}_{scan.stem}",
            )
        if left is None or not left.is_file():
            raise LayoutError(
                f"{scan}: a LiDAR scene needs the left image ({left or folder / 'left.png'}) "
                "for its size; not found"
            )
        frame = None if single is not None else scan.stem
        loaders.append(partial(_lidar_frame, folder, name, scan, left, right, calib, frame))
    return loaders


def _kitti_raw_frames(folder: Path) -> list[Callable[[], Scene]]:
    """Frames of a KITTI raw drive, as ``kitti-lidar`` frames; none when it is not a drive.

    The GT of each frame is its scan projected, as for ``velodyne_points/*.bin`` folders.
    """
    from dispeval_ros.io.kitti_raw import is_drive, open_drive

    if not is_drive(folder):
        return []
    drive = open_drive(folder)
    left, right, scans = (
        drive.streams[s].files for s in ("image_02", "image_03", "velodyne_points")
    )
    return [
        partial(
            _lidar_frame,
            folder,
            f"{folder.name}_{stem}",
            scan,
            image,
            other,
            drive.calib_folder,
            frame=stem,
        )
        for stem, scan, image, other in zip(drive.frames, scans, left, right, strict=True)
    ]


# ---------------------------------------------------------------------------------- public


def _folder(path: PathLike) -> Path:
    folder = Path(path)
    if not folder.exists():
        raise InputError(f"{folder}: scene folder not found")
    if not folder.is_dir():
        raise LayoutError(f"{folder}: expected a scene folder, got a file")
    return folder


_LOOKED_FOR = (
    "Disparity/NNNN.pfm (sceneflow), motorcycle_disp.npz (motorcycle-npz), "
    "disp0GT.pfm (middeval3), disp0.pfm (eth3d), groundtruth.png + info.txt "
    "(middlebury2001), *_left_disp.npy (tartanair), gt_disparity.png|disp_gt.png|"
    "disp_occ*.png (kitti), lidar.bin or velodyne_points/*.bin + KITTI calibration "
    "(kitti-lidar), image_02/data + velodyne_points/data (a KITTI raw drive)"
)


def _frames(folder: Path) -> list[Callable[[], Scene]]:
    """Loaders of every frame of ``folder`` in order; detection happens here, loading later."""
    frames = _sceneflow_frames(folder)
    if frames:
        camera = _sceneflow_camera(folder)
        return [partial(_sceneflow_frame, folder, frame, camera) for frame in frames]
    if (folder / MOTORCYCLE_NPZ).is_file():
        return [partial(_load_motorcycle_npz, folder)]
    if (folder / "disp0GT.pfm").is_file():
        return [partial(_load_middlebury2014, folder, "middeval3", "disp0GT.pfm")]
    if (folder / "disp0.pfm").is_file():
        return [partial(_load_middlebury2014, folder, "eth3d", "disp0.pfm")]
    if (folder / "groundtruth.png").is_file():
        if not (folder / "info.txt").is_file():
            raise LayoutError(
                f"{folder}: groundtruth.png found but not info.txt (Middlebury 2001/2003: its "
                f"first line is the GT scale); found {_files_preview(folder)}"
            )
        return [partial(_load_middlebury2001, folder)]
    frames = _tartanair_frames(folder)
    if frames:
        camera = _required_calib(folder, "Q.dat")
        return [partial(_tartanair_frame, folder, frame, camera) for frame in frames]
    gt_file = _kitti_gt(folder)
    if gt_file is not None:
        return [partial(_load_kitti, folder, gt_file)]
    lidar = _lidar_frames(folder) or _kitti_raw_frames(folder)
    if lidar:
        return lidar
    raise LayoutError(
        f"{folder}: not a recognised scene folder: looked for {_LOOKED_FOR}; "
        f"found {_files_preview(folder)}"
    )


def scene_folders(path: PathLike) -> list[Path]:
    """``path`` if it is a scene folder, else the scene folders in it (a dataset tree), sorted.

    A folder that is neither is its own :class:`LayoutError` (one line naming what was looked
    for); a subfolder that is not a scene is passed over.
    """
    folder = _folder(path)
    try:
        _frames(folder)
    except LayoutError as error:
        scenes = [
            child for child in sorted(folder.iterdir()) if child.is_dir() and _is_scene(child)
        ]
        if not scenes:
            raise LayoutError(f"{error} (nor a dataset tree: no scene folder in it)") from None
        return scenes
    return [folder]


def _is_scene(folder: Path) -> bool:
    try:
        _frames(folder)
    except LayoutError:
        return False
    return True


def load_scene(path: PathLike) -> Scene:
    """Load the scene in folder ``path``, recognising its layout by its files.

    For a sequence folder (SceneFlow, TartanAir) this is the first frame; see
    :func:`list_frames` for all of them.
    """
    return _frames(_folder(path))[0]()


def list_frames(path: PathLike) -> list[Scene]:
    """Every frame of the scene folder ``path`` (one for single-frame layouts)."""
    return [loader() for loader in _frames(_folder(path))]
