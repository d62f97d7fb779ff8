"""Sets given by the user's data rather than the GT's geometry: ROI labels and image texture."""

from __future__ import annotations

from collections.abc import Mapping

import cv2
import numpy as np

from dispeval_ros.core.criteria.base import (
    CriterionSet,
    _partitioning,
    size_text,
)
from dispeval_ros.errors import ConfigurationError, ShapeMismatchError


def roi_set(
    valid: np.ndarray,
    roi: np.ndarray,
    names: Mapping[int, str] | None = None,
) -> CriterionSet:
    """``roi`` / ``elsewhere`` from a mask, or named classes of a label image.

    With ``names`` (label value → class name) every listed value is a criterion and all
    other values form ``unlabelled``.
    """
    if roi.shape != valid.shape:
        raise ShapeMismatchError(
            f"the region-of-interest image is {size_text(roi.shape)} but the ground truth is "
            f"{size_text(valid.shape)}"
        )
    if not names:
        labels = np.where(roi.astype(bool, copy=False), 0, 1).astype(np.int32)
        return _partitioning("roi", labels, ("roi", "elsewhere"), "mask")
    values = sorted(names)
    criteria = (*(names[v] for v in values), "unlabelled")
    if len(set(criteria)) != len(criteria):
        raise ConfigurationError(f"label names must be unique, got {', '.join(criteria)}")
    lookup = np.full(int(max(int(roi.max()), *values)) + 1, len(values), np.int32)
    lookup[np.asarray(values, dtype=np.int64)] = np.arange(len(values), dtype=np.int32)
    labels = lookup[np.clip(roi.astype(np.int64), 0, None)]
    return _partitioning("roi", labels, criteria, "label image")


TEXTURE = ("textured", "textureless")
#: Middlebury 2001 taxonomy (Scharstein & Szeliski, MSR-TR-2001-81, §5.1): a pixel is
#: textureless where the squared horizontal intensity gradient, averaged over a square window
#: of this width, is below :data:`TEXTURE_THRESHOLD` (grey levels², 8-bit intensities).
TEXTURE_WINDOW = 3
TEXTURE_THRESHOLD = 4.0


def texture_set(
    image: np.ndarray,
    window: int = TEXTURE_WINDOW,
    threshold: float = TEXTURE_THRESHOLD,
) -> CriterionSet:
    """``textured`` / ``textureless`` from the left image alone (never from a method's output).

    The horizontal gradient is the forward difference ``I(x+1, y) − I(x, y)`` (0 in the last
    column); its square is box-averaged over ``window × window`` pixels (borders reflected).
    """
    if image.ndim != 2:
        raise ConfigurationError(f"the texture criteria need a grey image, got shape {image.shape}")
    if window < 1:
        raise ConfigurationError(f"the texture window must be at least 1 pixel, got {window}")
    grey = image.astype(np.float32)
    squared = np.zeros(grey.shape, np.float32)
    squared[:, :-1] = np.square(grey[:, 1:] - grey[:, :-1])
    mean = cv2.boxFilter(squared, -1, (window, window), borderType=cv2.BORDER_REFLECT_101)
    labels = (mean < threshold).astype(np.int32)
    return _partitioning(
        "texture",
        labels,
        TEXTURE,
        f"mean squared horizontal gradient over {window}×{window} < {threshold:g} grey levels²",
    )
