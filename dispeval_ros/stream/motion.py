"""The camera's motion for the pair stage: the stream's ``/tf`` and ``/tf_static`` over time.

Every ``/tf`` sample and ``/tf_static`` edge goes into a
:class:`~dispeval_ros.core.transform_history.TransformHistory` (tf2's lookup semantics), whose
``camera_motion`` and ``ready`` the pair stage's ego-motion residual asks. A sample the history
refuses (a second parent, a loop, too old, malformed) is kept out and noted, once per reason,
as a line the front end reports; nothing is silently lost.

A robot that publishes ``nav_msgs/Odometry`` only (no ``/tf``) feeds it through
:meth:`MotionSource.push_odometry` (its ``odom → child`` pose is a ``/tf`` edge), with the
camera's mount on that child given as :attr:`MotionSource.mount` where no ``/tf_static`` holds it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dispeval_ros.core.transform_history import TransformHistory
from dispeval_ros.core.transforms import StaticTransform, TransformTree
from dispeval_ros.errors import DispevalError
from dispeval_ros.io.messages import static_transforms_from_msg
from dispeval_ros.io.tf_messages import odometry_from_msg, transforms_from_msg
from dispeval_ros.stream.config import TF_TOPIC

MAX_NOTES = 20
"""Distinct refusals kept word for word (then only counted)."""


class MotionSource:
    """``/tf`` and ``/tf_static`` messages → a :class:`TransformHistory` (thread-safe)."""

    def __init__(self, static: TransformTree, static_topic: str) -> None:
        self.history = TransformHistory(static)
        self.static_topic = static_topic
        self.notes: dict[str, int] = {}
        """Each refusal's line → how often it happened."""
        self.mount: np.ndarray | None = None
        """The camera's mount (4×4: the odometry's child frame → the camera frame), for an
        odometry-only robot; None: the chain comes from /tf_static (or the odometry's child
        is the camera frame)."""
        self._odometry_child: str | None = None

    def takes(self, topic: str) -> bool:
        """Whether ``topic`` is one this source reads."""
        return topic in (TF_TOPIC, self.static_topic)

    def push(self, topic: str, msg: Any) -> None:
        """Add one message's transforms; what is refused is noted (:attr:`notes`)."""
        try:
            if topic == self.static_topic:
                self.history.add_static(static_transforms_from_msg(msg, topic))
                return
            samples = transforms_from_msg(msg, topic)
        except DispevalError as error:
            self._note(str(error))
            return
        for stamp, edge in samples:
            try:
                self.history.add(stamp, edge)
            except DispevalError as error:
                self._note(str(error))

    def push_odometry(self, topic: str, msg: Any) -> None:
        """Add one ``nav_msgs/Odometry`` as the /tf edge ``odom → child`` at its stamp."""
        try:
            stamp, edge = odometry_from_msg(msg, topic)
            self._odometry_child = self._odometry_child or edge.child
            self.history.add(stamp, edge)
        except DispevalError as error:
            self._note(str(error))

    def camera_motion(self, camera_frame: str, t0_ns: int, t1_ns: int) -> np.ndarray:
        """``TransformHistory.camera_motion``, the :attr:`mount` added once the frames are known."""
        self._mount(camera_frame)
        return self.history.camera_motion(camera_frame, t0_ns, t1_ns)

    def ready(self, stamp_ns: int, camera_frame: str | None = None) -> bool:
        """``TransformHistory.ready``, the :attr:`mount` added once the frames are known."""
        if camera_frame is not None:
            self._mount(camera_frame)
        return self.history.ready(stamp_ns, camera_frame)

    def answers_until(self, camera_frame: str | None = None) -> int | None:
        """``TransformHistory.answers_until``, the :attr:`mount` added once the frames are known."""
        if camera_frame is not None:
            self._mount(camera_frame)
        return self.history.answers_until(camera_frame)

    def _mount(self, camera_frame: str) -> None:
        """The mount as the static edge odometry child → ``camera_frame`` (once, when known)."""
        child = self._odometry_child
        if self.mount is None or child is None or child == camera_frame:
            return
        if camera_frame not in self.history.frames:
            try:
                self.history.add_static([StaticTransform(child, camera_frame, self.mount)])
            except DispevalError as error:
                self._note(str(error))

    def _note(self, text: str) -> None:
        if text in self.notes or len(self.notes) < MAX_NOTES:
            self.notes[text] = self.notes.get(text, 0) + 1
        else:
            self.notes["(other refusals)"] = self.notes.get("(other refusals)", 0) + 1

    def problems(self) -> list[str]:
        """The refusals as lines: ``/tf: … (3 times)``."""
        return [
            f"transforms: {text}" + (f" ({count} times)" if count > 1 else "")
            for text, count in self.notes.items()
        ]
