"""A site's network settings for tools that join a running dome (``--site SITE``).

``ant-operator`` and ``ant-bag`` talk to nodes that ``ant-dome up SITE`` started, so they must
use the site's ROS domain and discovery range, not the defaults of the shell they run in.
:func:`site_network` reads only the ``network:`` section of a site file (the format of
``excavation_bringup.site``, which checks the whole file); :func:`use_site_network` puts it
into the environment before rclpy starts.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from dataclasses import dataclass
from pathlib import Path

from excavation_common.errors import FieldError
from excavation_common.loaders import parse_yaml, read_text_bounded

DISCOVERY_RANGES = ("LOCALHOST", "SUBNET", "OFF", "SYSTEM_DEFAULT")
"""Values of ``ROS_AUTOMATIC_DISCOVERY_RANGE``."""

MAX_DOMAIN = 232
"""Largest ROS domain id rmw accepts (0..101 leave the ephemeral port range alone)."""


@dataclass(frozen=True)
class Network:
    """ROS domain id and discovery range of every process of a site."""

    domain: int = 0
    discovery_range: str = "LOCALHOST"

    def environment(self) -> dict[str, str]:
        """``ROS_DOMAIN_ID`` and ``ROS_AUTOMATIC_DISCOVERY_RANGE``."""
        return {
            "ROS_DOMAIN_ID": str(self.domain),
            "ROS_AUTOMATIC_DISCOVERY_RANGE": self.discovery_range,
        }


def site_network(path: str | Path) -> Network:
    """The ``network:`` section of the site file ``path`` (defaults where absent).

    Raises:
        FieldError: An unreadable file, or a domain or range that is not allowed (naming
            the file, the field and the value).
    """
    path = str(path)
    doc = parse_yaml(read_text_bounded(path), path)
    section = doc.get("network", {}) if isinstance(doc, dict) else None
    if section is None:
        section = {}
    if not isinstance(section, dict):
        raise FieldError(path, "network", section, "expected a mapping")
    domain = section.get("domain", Network.domain)
    if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= MAX_DOMAIN:
        raise FieldError(
            path, "network.domain", domain, f"expected an integer in 0 .. {MAX_DOMAIN}"
        )
    discovery = section.get("discovery_range", Network.discovery_range)
    if discovery not in DISCOVERY_RANGES:
        raise FieldError(
            path,
            "network.discovery_range",
            discovery,
            f"must be one of {', '.join(DISCOVERY_RANGES)}",
        )
    return Network(domain, discovery)


def use_site_network(path: str | Path, env: MutableMapping[str, str] | None = None) -> Network:
    """Set the site's domain and discovery range in ``env`` (default: this process's).

    Raises:
        FieldError: As :func:`site_network`.
    """
    network = site_network(path)
    (os.environ if env is None else env).update(network.environment())
    return network
