"""A site's network settings for tools that join a running dome (``--site SITE``).

``ant-operator`` and ``ant-bag`` talk to nodes that ``ant-dome up SITE`` started, so they must
use the site's ROS domain, discovery range and static peers, not the defaults of the shell
they run in. :func:`site_network` reads only the ``network:`` section of a site file (the
format of ``excavation_bringup.site``, which checks the whole file); :func:`use_site_network`
puts it into the environment before rclpy starts.

Static peers (``ROS_STATIC_PEERS``, semicolon-separated) are the hosts a node contacts by
unicast besides what automatic discovery finds: on a Wi-Fi link, where multicast is lost
or rate-limited, list every other host of the site. With ``discovery_range: LOCALHOST``
they are the only other hosts a node discovers (no multicast leaves the machine); ``OFF``
discovers nothing, static peers included (ROS 2's "Improved Dynamic Discovery" table), so
a site refuses static peers with ``OFF``.
"""

from __future__ import annotations

import ipaddress
import os
import re
from collections.abc import MutableMapping
from dataclasses import dataclass
from pathlib import Path

from excavation_common.errors import FieldError
from excavation_common.loaders import parse_yaml, read_text_bounded

DISCOVERY_RANGES = ("LOCALHOST", "SUBNET", "OFF", "SYSTEM_DEFAULT")
"""Values of ``ROS_AUTOMATIC_DISCOVERY_RANGE``."""

MAX_DOMAIN = 232
"""Largest ROS domain id rmw accepts (0..101 leave the ephemeral port range alone)."""


MAX_STATIC_PEERS = 32
"""Most static peers a site may list (rmw caps them too; a dome has a handful of hosts)."""

_HOSTNAME = re.compile(
    r"^(?=.{1,253}$)[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?(\.[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*$"
)


def valid_address(value: object) -> bool:
    """An IPv4 or IPv6 address or a host name (what ``ROS_STATIC_PEERS`` takes)."""
    if not isinstance(value, str):
        return False
    try:
        ipaddress.ip_address(value)
        return True
    except ValueError:
        return bool(_HOSTNAME.match(value))


OFF_WITH_PEERS = "discovery_range OFF discovers no peer, static ones included: use LOCALHOST"


def yaml_range(value: object) -> object:
    """A discovery range as written in YAML: an unquoted ``OFF`` reads as false (YAML 1.1)."""
    return "OFF" if value is False else value


@dataclass(frozen=True)
class Network:
    """ROS domain id, discovery range and static peers of every process of a site."""

    domain: int = 0
    discovery_range: str = "LOCALHOST"
    static_peers: tuple[str, ...] = ()

    def environment(self) -> dict[str, str]:
        """``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE`` and ``ROS_STATIC_PEERS``.

        ``ROS_STATIC_PEERS`` is empty without static peers (an inherited value would add
        peers the site does not name).
        """
        return {
            "ROS_DOMAIN_ID": str(self.domain),
            "ROS_AUTOMATIC_DISCOVERY_RANGE": self.discovery_range,
            "ROS_STATIC_PEERS": ";".join(self.static_peers),
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
    discovery = yaml_range(section.get("discovery_range", Network.discovery_range))
    if discovery not in DISCOVERY_RANGES:
        raise FieldError(
            path,
            "network.discovery_range",
            discovery,
            f"must be one of {', '.join(DISCOVERY_RANGES)}",
        )
    peers = section.get("static_peers", [])
    if not isinstance(peers, list) or len(peers) > MAX_STATIC_PEERS:
        raise FieldError(
            path, "network.static_peers", peers, f"expected a list of at most {MAX_STATIC_PEERS}"
        )
    for peer in peers:
        if not valid_address(peer):
            raise FieldError(
                path, "network.static_peers", peer, "expected an IP address or a host name"
            )
    if peers and discovery == "OFF":
        raise FieldError(path, "network.static_peers", peers, OFF_WITH_PEERS)
    return Network(domain, discovery, tuple(peers))


def use_site_network(path: str | Path, env: MutableMapping[str, str] | None = None) -> Network:
    """Set the site's network in ``env`` (default: this process's environment).

    Raises:
        FieldError: As :func:`site_network`.
    """
    network = site_network(path)
    (os.environ if env is None else env).update(network.environment())
    return network
