"""``dispeval info``'s transforms: /tf edges and spans, /tf_static edges, the camera's motion.

/tf is read into a :class:`~dispeval_ros.core.transform_history.TransformHistory` that keeps
every sample, so what it refuses (two parents, a loop, a bad rotation) is said per edge, as is
a sample logged after a later stamp (lookups sort them; a recorder's reordering shows here).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from dispeval_ros.core.transform_history import (
    EdgeSpan,
    ExtrapolationError,
    TransformHistory,
    format_stamp,
)
from dispeval_ros.errors import DispevalError
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.tf_messages import add_tf_message
from dispeval_ros.stream.config import TF_STATIC_TOPIC

TF_READ_LIMIT = 20_000
"""``/tf`` messages ``info`` reads at most (a longer ``/tf``: the spans of its start)."""
_FOREVER_NS = 1 << 62
"""The cache window of ``info``'s history: it keeps every sample it reads."""


@dataclass
class TransformFacts:
    """The bag's transforms: /tf edges with their spans, /tf_static edges, the camera's motion."""

    dynamic: list[EdgeSpan]
    static: list[tuple[str, str]]
    read: int
    """/tf messages read (at most :data:`TF_READ_LIMIT`)."""
    total: int
    camera: str | None
    motion: str | None
    """How the camera moves (``'stereo_left' moves through 'odom'``) or why it cannot."""
    problems: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, object]:
        """JSON form."""
        return {
            "tf": [
                {
                    "parent": e.parent,
                    "child": e.child,
                    "samples": e.samples,
                    "first_ns": e.first_ns,
                    "last_ns": e.last_ns,
                }
                for e in self.dynamic
            ],
            "tf_static": [{"parent": parent, "child": child} for parent, child in self.static],
            "tf_messages": {"read": self.read, "total": self.total},
            "camera_frame": self.camera,
            "ego_motion": self.motion,
            "problems": self.problems,
        }

    def lines(self) -> list[str]:
        """The human report."""
        out = []
        for e in self.dynamic:
            span = (e.last_ns - e.first_ns) / 1e9
            rate = f", {(e.samples - 1) / span:.3g} Hz" if span > 0 else ""
            out.append(
                f"/tf {e.parent} → {e.child}: {e.samples} samples, {format_stamp(e.first_ns)} "
                f"to {format_stamp(e.last_ns)} ({span:.9g} s{rate})"
            )
        if self.read < self.total:
            out.append(f"/tf: the spans of its first {self.read} of {self.total} messages")
        if self.static:
            edges = ", ".join(f"{parent} → {child}" for parent, child in self.static)
            out.append(f"/tf_static: {edges}")
        if self.motion:
            out.append(f"ego-motion: {self.motion}")
        return out + [f"note: {problem}" for problem in self.problems]


def transform_facts(
    source: BagSource, topics: dict[str, int], camera: str | None
) -> TransformFacts:
    """Read the TFMessage ``topics`` (name: count) into a history (/tf up to the limit)."""
    history = TransformHistory(cache_ns=_FOREVER_NS)
    problems: list[str] = []
    read = 0
    total = sum(count for name, count in topics.items() if name != TF_STATIC_TOPIC)
    messages = source.messages(list(topics), on_error=lambda error: problems.append(str(error)))
    try:
        for topic, _, msg in messages:
            static = topic == TF_STATIC_TOPIC
            if not static:
                if read == TF_READ_LIMIT:
                    break
                read += 1
            problems += add_tf_message(history, msg, topic, static=static)
    except DispevalError as error:  # damage: what came before it
        problems.append(str(error))
    finally:
        close = getattr(messages, "close", None)
        if close is not None:
            close()
    spans = history.spans()
    for span in spans:
        if span.late:
            problems.append(
                f"/tf {span.parent} → {span.child}: {span.late} sample(s) logged after a later "
                "stamp (out of order; lookups sort them by stamp)"
            )
    return TransformFacts(
        spans,
        sorted((e.parent, e.child) for e in history.static.edges.values()),
        read,
        total,
        camera,
        _motion(history, camera),
        list(dict.fromkeys(problems)),
    )


def _motion(history: TransformHistory, camera: str | None) -> str | None:
    """Whether /tf moves the camera frame, in one line."""
    spans = history.spans()
    if camera is None or not spans:
        return None if camera is None else "no /tf transform: no ego-motion"
    stamp = min(e.last_ns for e in spans)
    try:
        history.camera_motion(camera, stamp, stamp)
    except ExtrapolationError:
        pass  # the chain exists; its edges' spans do not all hold this stamp
    except DispevalError as error:
        return str(error)
    return f"the camera frame '{camera}' moves through '{history.fixed_frame(camera)}' on /tf"
