"""What a run's scores are measured against, in words, from its stored configuration.

The report's header and the PNG figures say it, so a reader of a LiDAR run knows that its
ground truth is a scan projected into the left camera (sparse points), and a reader of a
ground-truth-free run what stands in for the ground truth. Read from the configuration record
:meth:`~dispeval_ros.stream.config.CoreConfig.as_record` stores (``gt_kind``, ``gt_topic``,
``images``, ``extrinsic``, ``cloud_filter``; ``eval --out``: ``gt`` or ``scene`` and its
``frames``); results that record none say nothing.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from dispeval_ros.core.measures import GT_FREE_MEASURES
from dispeval_ros.io.scene_frames import GT_SOURCE_TEXT
from dispeval_ros.stream.config import TF_STATIC_TOPIC

POINTCLOUD = "pointcloud"
"""The ``gt_kind`` of a LiDAR run (:data:`~dispeval_ros.stream.config.GT_KINDS`)."""


def is_pointcloud(config: Mapping[str, Any]) -> bool:
    """Whether the run's ground truth is a LiDAR point cloud (sparse projected points)."""
    return config.get("gt_kind") == POINTCLOUD


def _images(config: Mapping[str, Any]) -> tuple[str, str] | None:
    images = config.get("images")
    if isinstance(images, list | tuple) and len(images) >= 2 and all(images[:2]):
        return str(images[0]), str(images[1])
    return None


def _gt_free_text(left: str, right: str) -> str:
    return (
        f"ground-truth-free measures ({', '.join(GT_FREE_MEASURES)}) against the rectified "
        f"images {left} and {right} (the right image warped by each estimate onto the left one)"
    )


def _eval_text(config: Mapping[str, Any]) -> str | None:
    """An ``eval --out`` run: the GT file, or the scene and the GT sources of its frames."""
    if isinstance(config.get("gt"), str):
        return f"ground truth: disparity file {config['gt']}"
    if not isinstance(config.get("scene"), str):
        return None
    frames = config.get("frames")
    listed = frames if isinstance(frames, list) else []
    sources = sorted(
        {str(f["gt_source"]) for f in listed if isinstance(f, dict) and f.get("gt_source")}
    )
    said = " and ".join(GT_SOURCE_TEXT.get(s, s) + "s" for s in sources)
    return f"ground truth: scene {config['scene']}" + (f" ({said})" if said else "")


def reference_text(config: Mapping[str, Any]) -> str | None:
    """One sentence naming the reference of the run's scores, or None when not recorded."""
    if config.get("command") == "eval":
        return _eval_text(config)
    kind, topic = config.get("gt_kind"), config.get("gt_topic")
    images = _images(config)
    if kind == "none":
        if images is None:
            return "no ground truth"
        return "no ground truth: " + _gt_free_text(*images)
    if not isinstance(topic, str) or not topic:
        return None
    if kind == POINTCLOUD:
        extrinsic = "given with the run" if config.get("extrinsic") else f"from {TF_STATIC_TOPIC}"
        text = (
            f"ground truth: {GT_SOURCE_TEXT['scan']} {topic} (sparse points: the cloud's points "
            f"seen by the left camera, extrinsic {extrinsic}"
        )
        if config.get("cloud_filter"):
            text += f", parallax filter {config['cloud_filter']}"
        text += ")"
    elif kind == "depth":
        text = f"ground truth: depth images {topic}, made disparity with the camera's f·B"
    else:
        scale = config.get("gt_scale")
        text = f"ground truth: disparity images {topic}" + (
            f" (scale {scale:g})" if isinstance(scale, int | float) else ""
        )
    if images is not None:
        text += "; and " + _gt_free_text(*images)
    return text
