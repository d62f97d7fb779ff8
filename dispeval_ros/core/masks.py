"""The one rule for masks: what a boolean, 0/1 or official mask image marks as inside.

Apart from the criteria (and their numba kernels) so that the file readers apply the same rule
without loading the evaluation.
"""

from __future__ import annotations

import numpy as np

from dispeval_ros.errors import InputError

#: An official mask image's values: 255 inside; 128 the points it leaves out on purpose (MiddEval3
#: and ETH3D occluded pixels, Middlebury ``disc.png`` pixels away from discontinuities); 0 no GT.
MASK_INSIDE, MASK_IMAGE_VALUES = 255, (0, 128, 255)


def inside_mask(what: str, mask: np.ndarray) -> np.ndarray:
    """The boolean "inside" of a mask: a boolean array, 0/1 values, or an official mask image.

    The one rule for every mask that reaches a criterion or a protocol. A mask image is
    255/128/0, so taking it as truthy would put the 128s (MiddEval3's occluded pixels) inside
    ``nonocc`` and leave ``occluded`` empty without a word; other values are ambiguous and refused.
    """
    array = np.asarray(mask)
    if array.dtype == np.bool_:
        return array
    if array.dtype.kind not in "uif" or array.size == 0:
        raise InputError(f"{what}: expected a boolean or 0/1 mask, or a mask image (255 = inside)")
    if array.dtype == np.uint8:
        values = np.flatnonzero(np.bincount(array.reshape(-1), minlength=256))
    else:
        values = np.unique(array)
    present = {float(v) for v in values}
    if present <= {0.0, 1.0}:
        return array == 1
    if present <= {float(v) for v in MASK_IMAGE_VALUES}:
        return array == MASK_INSIDE
    shown = ", ".join(f"{v:g}" for v in sorted(present)[:6]) + (", ..." if len(present) > 6 else "")
    raise InputError(
        f"{what} holds the values {shown}: expected a boolean mask, 0/1, or a mask image as the "
        "benchmarks write them (255 = inside, 128 = left out, 0 = no ground truth)"
    )
