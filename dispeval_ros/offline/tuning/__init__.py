"""``dispeval tune``: sweep the parameters of an OpenCV stereo matcher, judged by A* Groups.

``space`` (a space file, checked and expanded into named configurations) and ``sweep`` (the
configurations' maps scored on scene frames into one resumable results database). The
parameters themselves (stereo_image_proc's names, ranges and defaults, mapped once onto
:class:`~dispeval_ros.testbed.methods.StereoMethod`) are in
:mod:`dispeval_ros.testbed.node_parameters`, which the test-bed's ROS disparity node reads too.
"""
