"""The camera's motion for the pair stage: the stream's ``/tf`` and ``/tf_static`` over time.

Every ``/tf`` sample and ``/tf_static`` edge goes into a
:class:`~dispeval_ros.core.transform_history.TransformHistory` (tf2's lookup semantics), whose
``camera_motion`` and ``ready`` the pair stage's ego-motion residual asks. A sample the history
refuses (a second parent, a loop, too old, malformed) is kept out and noted, once per reason,
as a line the front end reports; nothing is silently lost.
"""

from __future__ import annotations

from typing import Any

from dispeval_ros.core.transform_history import TransformHistory
from dispeval_ros.core.transforms import TransformTree
from dispeval_ros.errors import DispevalError
from dispeval_ros.io.messages import static_transforms_from_msg
from dispeval_ros.io.tf_messages import transforms_from_msg
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
