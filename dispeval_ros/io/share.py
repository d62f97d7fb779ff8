"""Where the package's shared files are: source checkout, pip install, or a colcon workspace.

The same files (config/, bags/, launch/) are installed to ``share/dispeval_ros`` by pip and by
colcon; a colcon workspace is found through the ament index (``AMENT_PREFIX_PATH``, which
``source install/setup.bash`` sets), as ``ament_index_python`` finds it, without importing ROS.
"""

from __future__ import annotations

import os
import sys
from importlib import metadata
from pathlib import Path

PACKAGE = "dispeval_ros"
_SOURCE_ROOT = Path(__file__).resolve().parents[2]


def ament_share_directories() -> list[Path]:
    """``PREFIX/share/dispeval_ros`` of every ament prefix that registered the package."""
    found = []
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if not prefix:
            continue
        marker = Path(prefix) / "share" / "ament_index" / "resource_index" / "packages" / PACKAGE
        if marker.is_file():
            found.append(Path(prefix) / "share" / PACKAGE)
    return found


def shared_file_candidates(relative: str) -> list[Path]:
    """Every place ``relative`` (e.g. ``config/x.xml``) may be, most specific first."""
    found = [_SOURCE_ROOT / relative]  # source checkout or editable install
    found.extend(share / relative for share in ament_share_directories())
    found.append(Path(sys.prefix) / "share" / PACKAGE / relative)
    try:  # installed as a data file of the distribution (pip)
        files = metadata.distribution(PACKAGE).files or []
    except metadata.PackageNotFoundError:
        files = []
    suffix = f"{PACKAGE}/{relative}"
    found.extend(
        Path(str(file.locate())) for file in files if str(file).replace("\\", "/").endswith(suffix)
    )
    return found
