"""Error images for RViz / Foxglove: absolute error, and a colour rendering with the criteria."""

from __future__ import annotations

import cv2
import numpy as np

from dispeval_ros.core.criteria import Partition


def colour_error(error: np.ndarray, partition: Partition, max_error: float = 4.0) -> np.ndarray:
    """RGB8 rendering of an error image, with the criteria visible.

    Error magnitude in the turbo colour map (0 → ``max_error`` px), black where not evaluated,
    and the borders between criteria cells drawn in white.
    """
    finite = np.isfinite(error)
    clipped = np.clip(np.where(finite, error, 0.0), 0.0, max_error)
    scaled = (clipped * (255.0 / max_error)).astype(np.uint8)
    bgr = cv2.applyColorMap(scaled, cv2.COLORMAP_TURBO)
    rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    rgb[~finite] = 0
    cells = partition.cells
    border = np.zeros(cells.shape, bool)
    border[:, 1:] |= cells[:, 1:] != cells[:, :-1]
    border[1:, :] |= cells[1:, :] != cells[:-1, :]
    rgb[border & (cells >= 0)] = 255
    return rgb
