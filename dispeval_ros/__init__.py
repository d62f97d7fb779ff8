"""dispeval_ros: judge stereo methods by their disparity maps (placeholder, filled below)."""
