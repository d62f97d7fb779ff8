"""File readers of the core engine: disparity maps, masks, calibrations and scene folders."""

from dispeval_ros.io.calib import read_calib
from dispeval_ros.io.files import (
    read_disparity,
    read_mask,
    read_pfm,
    write_disparity_png16,
    write_pfm,
)
from dispeval_ros.io.scenes import Scene, list_frames, load_scene

__all__ = [
    "Scene",
    "list_frames",
    "load_scene",
    "read_calib",
    "read_disparity",
    "read_mask",
    "read_pfm",
    "write_disparity_png16",
    "write_pfm",
]
