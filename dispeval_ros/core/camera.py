"""The stereo camera record used to turn disparities into depth."""

from __future__ import annotations

import math
from dataclasses import dataclass

from dispeval_ros.errors import CalibrationError


@dataclass(frozen=True)
class Camera:
    """Rectified stereo camera: depth ``Z = f·B / (d + doffs)``.

    ``f`` is the focal length in pixels, ``baseline`` the distance between the optical
    centres (metres unless ``unit`` says otherwise) and ``doffs`` the difference of the
    principal points' x-coordinates in pixels (0 for ROS-rectified cameras).
    """

    f: float
    baseline: float
    doffs: float = 0.0
    unit: str = "m"

    def __post_init__(self) -> None:
        for name in ("f", "baseline", "doffs"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise CalibrationError(f"camera {name} must be a finite number, got {value!r}")
        if self.f <= 0:
            raise CalibrationError(f"camera focal length must be > 0 px, got {self.f}")
        if self.baseline <= 0:
            raise CalibrationError(f"camera baseline must be > 0, got {self.baseline}")

    @property
    def fb(self) -> float:
        """The product ``f·B`` that converts disparity to depth."""
        return self.f * self.baseline

    def depth(self, disparity: float) -> float:
        """Depth of one disparity value (``inf`` where ``d + doffs <= 0``)."""
        denominator = disparity + self.doffs
        return self.fb / denominator if denominator > 0 else math.inf
