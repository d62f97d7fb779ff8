"""Synthetic rectified stereo pairs with exact ground truth, rendered by ray casting.

The public face of the test-bed scene, kept so existing imports work: the world records live
in :mod:`.world`, ray casting and shading in :mod:`.render`, the demo scene and the driving
sequence in :mod:`.presets`.
"""

from dispeval_ros.testbed.presets import (
    CAMERA_HEIGHT,
    KITTI_CX,
    KITTI_CY,
    KITTI_F,
    KITTI_HEIGHT,
    KITTI_WIDTH,
    NEAREST,
    driving_setup,
    driving_world_at,
    make_driving_sequence,
    make_scene,
    scene_setup,
)
from dispeval_ros.testbed.render import (
    FACE_NEG_X,
    FACE_NEG_Y,
    FACE_NEG_Z,
    FACE_POS_X,
    FACE_POS_Y,
    FACE_POS_Z,
    StereoFrame,
    View,
    frame_from_views,
    render_pair,
    render_stereo,
    render_view,
)
from dispeval_ros.testbed.world import (
    FAR_WALL,
    FIRST_BOX,
    GROUND,
    NOTHING,
    Box,
    LaneLine,
    StereoRig,
    Vec3,
    World,
)

__all__ = [
    "CAMERA_HEIGHT",
    "FACE_NEG_X",
    "FACE_NEG_Y",
    "FACE_NEG_Z",
    "FACE_POS_X",
    "FACE_POS_Y",
    "FACE_POS_Z",
    "FAR_WALL",
    "FIRST_BOX",
    "GROUND",
    "KITTI_CX",
    "KITTI_CY",
    "KITTI_F",
    "KITTI_HEIGHT",
    "KITTI_WIDTH",
    "NEAREST",
    "NOTHING",
    "Box",
    "LaneLine",
    "StereoFrame",
    "StereoRig",
    "Vec3",
    "View",
    "World",
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
