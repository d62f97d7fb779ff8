"""8-bit grey images from decoded frames, for the ground-truth-free measures (OpenCV).

Apart from :mod:`dispeval_ros.io.messages` so that decoding messages loads no OpenCV.
"""

from __future__ import annotations

import cv2
import numpy as np

from dispeval_ros.errors import InputError
from dispeval_ros.io.messages import ImageFrame, _where

__all__ = ["GREY_SOURCES", "grey_from_frame", "stereo_grey"]

#: Image encodings the ground-truth-free measures read (8-bit; colour is converted to grey).
GREY_SOURCES = {"mono8": None, "8UC1": None, "rgb8": "RGB", "bgr8": "BGR"}


def grey_from_frame(frame: ImageFrame, topic: str = "") -> np.ndarray:
    """An 8-bit grey image from a decoded mono8/8UC1/rgb8/bgr8 frame (BT.601 weights)."""
    if frame.encoding not in GREY_SOURCES:
        raise InputError(
            f"{_where(topic, 'Image')}: encoding '{frame.encoding}' is not an 8-bit grey or "
            f"colour image; the ground-truth-free measures need one of {', '.join(GREY_SOURCES)}"
        )
    order = GREY_SOURCES[frame.encoding]
    if order is None:
        return np.ascontiguousarray(frame.array)
    code = cv2.COLOR_RGB2GRAY if order == "RGB" else cv2.COLOR_BGR2GRAY
    return cv2.cvtColor(np.ascontiguousarray(frame.array), code)


def stereo_grey(
    left: ImageFrame, right: ImageFrame, left_topic: str = "", right_topic: str = ""
) -> tuple[np.ndarray, np.ndarray]:
    """Both rectified images as 8-bit grey; colour beside grey is refused (one line)."""
    kinds = {name: GREY_SOURCES.get(name) is not None for name in (left.encoding, right.encoding)}
    if left.encoding != right.encoding and kinds.get(left.encoding) != kinds.get(right.encoding):
        shown = {True: "colour", False: "grey"}
        raise InputError(
            f"the left image{' on ' + left_topic if left_topic else ''} is {left.encoding} "
            f"({shown[kinds[left.encoding]]}) but the right image"
            f"{' on ' + right_topic if right_topic else ''} is {right.encoding} "
            f"({shown[kinds[right.encoding]]}): publish both in one encoding"
        )
    return grey_from_frame(left, left_topic), grey_from_frame(right, right_topic)
