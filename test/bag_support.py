"""What the tests of ``dispeval bag`` share: the synthetic drive's methods, its command line,
the same bag in the ROS 1 format, and what "the same database" means.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

from dispeval_ros.offline.make_bag import GT_TOPIC, LEFT_INFO, RIGHT_INFO, disparity_topic

METHODS = ("bm_fast", "sgbm", "sgbm_3way")


def method_args() -> list[str]:
    args: list[str] = []
    for name in METHODS:
        args += ["--method", f"{name}={disparity_topic(name)}"]
    return args


def bag_args(bag: Path, out: Path, *extra: str) -> list[str]:
    return [
        "bag",
        str(bag),
        "--gt",
        GT_TOPIC,
        *method_args(),
        "--camera-info",
        LEFT_INFO,
        RIGHT_INFO,
        "--out",
        str(out),
        "--quiet",
        *extra,
    ]


def as_ros1(source: Path, target: Path) -> None:
    """Convert a rosbag2 (sqlite3) bag to a ROS 1 bag, as rosbags' converter does."""
    from rosbags.convert import convert

    convert(
        srcs=[source],
        dst=target,
        dst_storage="sqlite3",
        dst_version=8,
        compress=None,
        compress_mode="file",
        default_typestore=None,
        typestore=None,
        exclude_topics=[],
        include_topics=[],
        exclude_msgtypes=[],
        include_msgtypes=[],
    )


def database_content(folder: Path) -> tuple[list[tuple], ...]:
    """Every table's rows in a canonical order (what 'the same database' means).

    The provenance record is left out: it says how a database was made (which inputs, which
    merge), so it differs by design between an uninterrupted run, a merge and a resume.
    """
    connection = sqlite3.connect(folder / "results.sqlite")
    tables = [
        row[0]
        for row in connection.execute(
            "SELECT name FROM sqlite_master WHERE type='table' AND name != 'provenance' "
            "ORDER BY name"
        )
    ]
    content = tuple(
        sorted(connection.execute(f'SELECT * FROM "{table}"').fetchall(), key=repr)
        for table in tables
    )
    connection.close()
    return content
