"""Synthetic stereo test-bed: ray-cast scenes with exact ground truth, and OpenCV methods.

Used by ``dispeval demo`` (no downloads needed) and by the bag generator.
"""

from dispeval_ros.testbed.methods import StereoMethod, default_methods, default_num_disparities
from dispeval_ros.testbed.scene import (
    FAR_WALL,
    FIRST_BOX,
    GROUND,
    NOTHING,
    Box,
    LaneLine,
    StereoFrame,
    StereoRig,
    View,
    World,
    driving_setup,
    driving_world_at,
    frame_from_views,
    make_driving_sequence,
    make_scene,
    render_pair,
    render_stereo,
    render_view,
    scene_setup,
)

__all__ = [
    "FAR_WALL",
    "FIRST_BOX",
    "GROUND",
    "NOTHING",
    "Box",
    "LaneLine",
    "StereoFrame",
    "StereoMethod",
    "StereoRig",
    "View",
    "World",
    "default_methods",
    "default_num_disparities",
    "driving_setup",
    "driving_world_at",
    "frame_from_views",
    "make_driving_sequence",
    "make_scene",
    "render_pair",
    "render_stereo",
    "render_view",
    "scene_setup",
]
