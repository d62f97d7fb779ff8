"""The names of the topics dispeval publishes, for every transport (rclpy nodes and DDS).

Written once here so that the ROS and the DDS front ends, which must interoperate, cannot
drift apart.
"""

from __future__ import annotations

NAMESPACE = "/dispeval"
SCORES_TOPIC = f"{NAMESPACE}/scores"
"""Every frame's scores and problems (``diagnostic_msgs/msg/DiagnosticArray``)."""
GROUPS_TOPIC = f"{NAMESPACE}/groups"
"""The A* Groups of the current sequence (``diagnostic_msgs/msg/DiagnosticArray``, latched)."""
VECTOR_LEAF = "vector"
VECTOR_LABELS_LEAF = "vector_labels"
ERROR_LEAF = "error"
ERROR_COLOR_LEAF = "error_color"


def method_topic(method: str, leaf: str) -> str:
    """``/dispeval/METHOD/LEAF``: where a method's vector, labels and error images go."""
    return f"{NAMESPACE}/{method}/{leaf}"
