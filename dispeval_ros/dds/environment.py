"""Where the DDS front ends run: the Cyclone DDS binding, the domain id, the configuration.

The configuration follows Cyclone DDS and ROS 2 conventions, so ``dispeval`` sees what a ROS 2
node on the same machine sees:

- ``--dds-config FILE`` sets ``CYCLONEDDS_URI`` for this process (``--dds-config localhost``
  names the shipped ``config/cyclonedds_localhost.xml``: loopback only, no multicast);
- without it, an existing ``CYCLONEDDS_URI`` is used as it is;
- without either, Cyclone DDS's defaults apply (the best network interface, multicast
  discovery), exactly like a ROS 2 node started without configuration. The localhost
  configuration is deliberately not the default: it could never see a robot on the network.

The domain id is ``--domain-id``, else ``ROS_DOMAIN_ID``, else 0.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from types import ModuleType

from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.share import shared_file_candidates

LOCALHOST_CONFIG = "cyclonedds_localhost.xml"
MAX_DOMAIN_ID = 232
"""The largest domain id whose RTPS ports stay below 65536 (ROS 2 uses 0–101 and 215–232)."""
INSTALL_HINT = "pip install 'dispeval_ros[dds]'"


def require_cyclonedds() -> ModuleType:
    """The ``cyclonedds`` package, or a one-line ConfigurationError saying how to install it."""
    try:
        import cyclonedds
        import cyclonedds.domain  # the compiled layer and the C library load here
    except ImportError as error:
        raise ConfigurationError(
            f"the DDS transport needs the Cyclone DDS Python binding ({error}); "
            f"install it with: {INSTALL_HINT}"
        ) from None
    except OSError as error:  # the bundled or system C library cannot be loaded
        raise ConfigurationError(
            f"the Cyclone DDS library cannot be loaded ({error}); reinstall it with: {INSTALL_HINT}"
        ) from None
    return cyclonedds


def localhost_config() -> Path:
    """The shipped same-host configuration (source checkout, pip or colcon ``share/``)."""
    for candidate in shared_file_candidates(f"config/{LOCALHOST_CONFIG}"):
        if candidate.is_file():
            return candidate
    raise ConfigurationError(
        f"the shipped {LOCALHOST_CONFIG} is not installed here; "
        "pass your own Cyclone DDS XML with --dds-config FILE"
    )


def resolve_config(dds_config: str | Path | None) -> Path | None:
    """The configuration file ``--dds-config`` names (``localhost`` = the shipped one)."""
    if dds_config is None:
        return None
    if str(dds_config) == "localhost":
        return localhost_config()
    path = Path(dds_config).expanduser()
    if not path.is_file():
        raise ConfigurationError(
            f"--dds-config {dds_config}: no such file; expected a Cyclone DDS XML configuration "
            "(or 'localhost' for the shipped same-host one)"
        )
    return path.resolve()


def configure(dds_config: str | Path | None) -> str | None:
    """Set ``CYCLONEDDS_URI`` from ``--dds-config`` before any participant exists.

    Returns the configuration in effect (a ``file://`` URI, the inherited variable, or None
    for Cyclone's defaults).
    """
    path = resolve_config(dds_config)
    if path is not None:
        os.environ["CYCLONEDDS_URI"] = path.as_uri()
    return os.environ.get("CYCLONEDDS_URI") or None


def domain_id(value: int | None = None) -> int:
    """``--domain-id``, else ``ROS_DOMAIN_ID``, else 0; checked to be a usable DDS domain."""
    where = "--domain-id"
    if value is None:
        text = os.environ.get("ROS_DOMAIN_ID", "").strip()
        if not text:
            return 0
        where = "ROS_DOMAIN_ID"
        try:
            value = int(text)
        except ValueError:
            raise ConfigurationError(f"ROS_DOMAIN_ID is '{text}', expected a number") from None
    if not 0 <= value <= MAX_DOMAIN_ID:
        raise ConfigurationError(f"{where} {value} is out of range; expected 0 to {MAX_DOMAIN_ID}")
    return value


def describe(uri: str | None, domain: int) -> str:
    """``domain 42, config file:///…`` for messages."""
    if uri is None:
        return f"domain {domain}, Cyclone DDS defaults"
    shown = uri if len(uri) <= 120 else uri[:117] + "..."
    return f"domain {domain}, CYCLONEDDS_URI={shown}"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--domain-id`` and ``--dds-config`` (the same in every DDS command)."""
    group = parser.add_argument_group("DDS")
    group.add_argument(
        "--domain-id",
        type=int,
        default=None,
        metavar="N",
        help="DDS domain (= ROS_DOMAIN_ID of the ROS 2 nodes; default: $ROS_DOMAIN_ID, else 0)",
    )
    group.add_argument(
        "--dds-config",
        default=None,
        metavar="FILE",
        help="Cyclone DDS XML configuration (sets CYCLONEDDS_URI); 'localhost' = the shipped "
        "same-host one; default: $CYCLONEDDS_URI, else Cyclone's defaults (as a ROS 2 node)",
    )
