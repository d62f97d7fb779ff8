"""``dispeval tune``: sweep the parameters of an OpenCV stereo matcher, judged by A* Groups.

``parameters`` (stereo_image_proc's parameter names, ranges and defaults, mapped once onto
:class:`~dispeval_ros.testbed.methods.StereoMethod`), ``space`` (a space file, checked and
expanded into named configurations) and ``sweep`` (the configurations' maps scored on scene
frames into one resumable results database).
"""
