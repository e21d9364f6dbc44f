"""A site's hosts on one machine: network namespaces joined by virtual links (a rehearsal).

``ant-dome rehearse SITE`` with robots on their own hosts (``hosts``, ``robots[k].host``)
gives each host a Linux network namespace of its own: the dome PC's holds a bridge, each
robot host's namespace is joined to it by a veth pair, and every host gets its address from
the site on its one interface. Only loopback and these links exist in the namespaces, so
nothing a rehearsal sends can leave the machine, and the addresses must lie in
198.18.0.0/15 (:data:`REHEARSAL_NETWORK`, RFC 2544's benchmarking range), which no real
network routes. A robot host's link can be taken down and up again (a drill's dropped
radio link), and every namespace is removed when the rehearsal ends, by :meth:`remove`
or, after a crash, by the next rehearsal with the same tag.

Needs ``ip`` (iproute2) and the privilege to create namespaces (root, or CAP_SYS_ADMIN and
CAP_NET_ADMIN). Processes run in a namespace through ``ip netns exec NS`` (:meth:`prefix`),
which execs the command: the process's pid is the node's, so signals reach it.
"""

from __future__ import annotations

import ipaddress
import shutil
import subprocess
from dataclasses import dataclass

REHEARSAL_NETWORK = ipaddress.ip_network("198.18.0.0/15")
"""The addresses a rehearsal's hosts may have (RFC 2544: for benchmarking, never routed)."""


class VirtualHostsError(RuntimeError):
    """A namespace or link could not be made (the message names the command and its error)."""


def rehearsal_address_problem(address: str) -> str | None:
    """Why ``address`` cannot be a rehearsal host's, or ``None`` when it can."""
    try:
        ip = ipaddress.ip_address(address)
    except ValueError:
        return f"a rehearsal's hosts need IPv4 addresses in {REHEARSAL_NETWORK}"
    if ip not in REHEARSAL_NETWORK or ip in (
        REHEARSAL_NETWORK.network_address,
        REHEARSAL_NETWORK.broadcast_address,
    ):
        return f"a rehearsal's hosts need addresses in {REHEARSAL_NETWORK} (RFC 2544)"
    return None


@dataclass(frozen=True)
class VirtualHost:
    """One host: its site name, address, namespace and (a robot host's) link names."""

    name: str
    address: str
    namespace: str
    link: str  # the veth end in the dome PC's namespace (empty for the dome PC)


class VirtualHosts:
    """Namespaces for the hosts ``[(name, address), ...]``, the dome PC first.

    Args:
        hosts: Each host's site name and address (in :data:`REHEARSAL_NETWORK`).
        tag: A short tag that makes the names unique on this machine (digits and letters,
            at most 6): namespaces ``ant<tag>-<i>``, links ``ant<tag>v<i>``.
    """

    def __init__(self, hosts: list[tuple[str, str]], tag: str) -> None:
        if not hosts:
            raise ValueError("no hosts")
        if not (tag.isalnum() and 0 < len(tag) <= 6):
            raise ValueError(f"tag {tag!r}: expected 1 to 6 letters or digits")
        for name, address in hosts:
            problem = rehearsal_address_problem(address)
            if problem:
                raise ValueError(f"host {name}: address {address!r}: {problem}")
        self.tag = tag
        self.hosts = [
            VirtualHost(name, address, f"ant{tag}-{i}", f"ant{tag}v{i}" if i else "")
            for i, (name, address) in enumerate(hosts)
        ]
        self.created: list[str] = []

    @property
    def dome(self) -> VirtualHost:
        """The dome PC (the first host)."""
        return self.hosts[0]

    def host(self, name: str) -> VirtualHost:
        """The host called ``name``.

        Raises:
            KeyError: No such host.
        """
        for h in self.hosts:
            if h.name == name:
                return h
        raise KeyError(f"no host {name!r} (hosts: {', '.join(h.name for h in self.hosts)})")

    def prefix(self, name: str) -> list[str]:
        """The command prefix that runs a process on host ``name``."""
        return ["ip", "netns", "exec", self.host(name).namespace]

    # --- making and removing ------------------------------------------------------------------

    @staticmethod
    def _ip(*args: str) -> None:
        result = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30)
        if result.returncode:
            raise VirtualHostsError(f"ip {' '.join(args)}: {result.stderr.strip()}")

    @staticmethod
    def _no_ipv6(namespace: str) -> None:
        """No IPv6 in ``namespace``: no link-local addresses, no neighbour discovery.

        Its links then carry the site's IPv4 addresses and nothing else.
        """
        for key in ("all", "default"):
            result = subprocess.run(
                [
                    "ip",
                    "netns",
                    "exec",
                    namespace,
                    "sysctl",
                    "-q",
                    "-w",
                    f"net.ipv6.conf.{key}.disable_ipv6=1",
                ],
                capture_output=True,
                text=True,
                timeout=30,
            )
            if result.returncode:
                raise VirtualHostsError(f"disabling IPv6 in {namespace}: {result.stderr.strip()}")

    def create(self) -> None:
        """Make the namespaces, the bridge and the links; on failure remove what was made.

        Raises:
            VirtualHostsError: ``ip`` is missing, or a step failed (e.g. no privilege).
        """
        if shutil.which("ip") is None:
            raise VirtualHostsError("the rehearsal of several hosts needs iproute2's `ip`")
        self.remove()  # a crashed rehearsal with this tag may have left its namespaces
        prefix = REHEARSAL_NETWORK.prefixlen
        try:
            for h in self.hosts:
                self._ip("netns", "add", h.namespace)
                self.created.append(h.namespace)
                self._ip("-n", h.namespace, "link", "set", "lo", "up")
                self._no_ipv6(h.namespace)
            dome = self.dome.namespace
            self._ip("-n", dome, "link", "add", "br0", "type", "bridge")
            self._ip("-n", dome, "addr", "add", f"{self.dome.address}/{prefix}", "dev", "br0")
            self._ip("-n", dome, "link", "set", "br0", "up")
            for h in self.hosts[1:]:
                peer = f"{h.link}r"
                self._ip("link", "add", h.link, "netns", dome, "type", "veth", "peer", "name", peer)
                self._ip("link", "set", peer, "netns", h.namespace)
                self._ip("-n", dome, "link", "set", h.link, "master", "br0")
                self._ip("-n", dome, "link", "set", h.link, "up")
                self._ip("-n", h.namespace, "addr", "add", f"{h.address}/{prefix}", "dev", peer)
                self._ip("-n", h.namespace, "link", "set", peer, "up")
        except (VirtualHostsError, OSError, subprocess.SubprocessError) as exc:
            self.remove()
            raise VirtualHostsError(f"cannot make the rehearsal's hosts: {exc}") from exc

    def remove(self) -> None:
        """Delete every namespace of this tag (their links and bridge go with them)."""
        names = {h.namespace for h in self.hosts} | set(self.created)
        for ns in sorted(names):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=30)
        self.created = []

    def set_link(self, name: str, up: bool) -> None:
        """Take robot host ``name``'s link down (``up`` False) or bring it back up.

        Raises:
            ValueError: ``name`` is the dome PC (it has no link of its own).
            VirtualHostsError: ``ip`` failed.
        """
        h = self.host(name)
        if not h.link:
            raise ValueError(f"{name} is the dome PC: drop a robot host's link")
        self._ip("-n", self.dome.namespace, "link", "set", h.link, "up" if up else "down")

    def __enter__(self) -> VirtualHosts:
        self.create()
        return self

    def __exit__(self, *exc) -> None:
        self.remove()
