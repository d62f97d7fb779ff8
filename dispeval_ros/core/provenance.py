"""A record of how each number was made: project version, configuration and its hash, inputs.

Every results database and JSON carries one, so a published number can be traced and re-made:
the configuration (a protocol's record or a command's options) is hashed as canonical JSON,
and every input file or message stream scored is named with its digest (a file's sha256; a
stream's BLAKE3, keyed by the algorithm's name; computed by :mod:`dispeval_ros.io.provenance`;
nothing here reads files).
"""

from __future__ import annotations

from collections.abc import Mapping

from dispeval_ros.core.protocols import config_sha256
from dispeval_ros.version import __version__

PROJECT = "dispeval_ros"


def provenance_record(
    configuration: Mapping[str, object], inputs: Mapping[str, object]
) -> dict[str, object]:
    """``{"project", "version", "configuration", "configuration_sha256", "inputs"}``."""
    return {
        "project": PROJECT,
        "version": __version__,
        "configuration": dict(configuration),
        "configuration_sha256": config_sha256(configuration),
        "inputs": dict(inputs),
    }
