"""A static camera for ``make-bag --static N``: one frame recorded N times with sensor noise.

Flicker (``dispeval bag --flicker``) is the temporal noise of a camera that does not move; a
bag of a scene seen N times by a standing rig, each frame with its own sensor noise, lets the
stereo methods' flicker be measured where the truth is known: the scene is the same, so every
change of an estimate from frame to frame is noise. The noise is uniform integer grey levels
in ``[−noise, noise]``, independent per pixel, image and frame (a bounded noise: within the
photometric check's threshold, no pixel reads as moving). Any pose (``odometry``) of the frame
is repeated: the rig stands still on ``/tf`` too.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import TYPE_CHECKING

from dispeval_ros.errors import ConfigurationError

if TYPE_CHECKING:  # (the CLI reads the default without importing the bag writer)
    import numpy as np

    from dispeval_ros.offline.make_bag import BagFrame

DEFAULT_SENSOR_NOISE = 2
"""Grey levels of sensor noise per frame with ``--static`` (±2: a good camera's read noise)."""


def static_frames(
    frame: BagFrame, count: int, fps: float, noise: int = DEFAULT_SENSOR_NOISE, seed: int = 0
) -> Iterator[BagFrame]:
    """``count`` frames of ``frame`` at ``fps``, each image with fresh noise of ±``noise``."""
    if count < 1 or noise < 0:
        raise ConfigurationError(
            f"--static needs at least 1 frame and a sensor noise ≥ 0, got {count} and {noise}"
        )
    import numpy as np

    rng = np.random.default_rng(seed)

    def shaken(image: np.ndarray) -> np.ndarray:
        if noise == 0:
            return image
        top = np.iinfo(image.dtype).max if image.dtype.kind in "ui" else 255
        grain = rng.integers(-noise, noise + 1, image.shape)
        return np.clip(image.astype(np.int64) + grain, 0, top).astype(image.dtype)

    for index in range(count):
        yield dataclasses.replace(
            frame,
            left=shaken(frame.left),
            right=shaken(frame.right),
            stamp=index / fps,
            stamps=None,  # (a recording's own stamps would all be the first frame's)
        )
