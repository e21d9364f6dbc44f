"""A rehearsal's hosts: network namespaces on one machine, joined by links that can drop."""

from __future__ import annotations

import subprocess

import pytest

from excavation_bringup.virtual_hosts import (
    VirtualHosts,
    rehearsal_address_problem,
)


def _netns() -> set[str]:
    out = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    return {line.split()[0] for line in out.splitlines() if line.strip()}


def _in(hosts: VirtualHosts, name: str, *cmd: str) -> str:
    return subprocess.run(
        hosts.prefix(name) + list(cmd), capture_output=True, text=True, timeout=30
    ).stdout


def test_each_host_has_its_namespace_its_address_and_nothing_else():
    hosts = VirtualHosts([("dome", "198.18.0.1"), ("robot0", "198.18.0.2")], "tvh1")
    with hosts:
        assert {"anttvh1-0", "anttvh1-1"} <= _netns()
        robot = _in(hosts, "robot0", "ip", "-o", "addr")
        assert "198.18.0.2/15" in robot and "inet6" not in robot  # no IPv6 at all
        links = _in(hosts, "robot0", "ip", "-o", "link").splitlines()
        assert [line.split(":")[1].strip().split("@")[0] for line in links] == ["lo", "anttvh1v1r"]
        routes = _in(hosts, "robot0", "ip", "route")
        assert routes.split()[:3] == ["198.18.0.0/15", "dev", "anttvh1v1r"]
        assert len(routes.splitlines()) == 1  # no default route: nowhere else to go
        dome = _in(hosts, "dome", "ip", "-o", "link")
        assert "br0" in dome and "anttvh1v1@" in dome
        hosts.set_link("robot0", False)
        assert "state DOWN" in _in(hosts, "dome", "ip", "-o", "link", "show", "anttvh1v1")
        hosts.set_link("robot0", True)
        assert (
            "DOWN"
            not in _in(hosts, "dome", "ip", "-o", "link", "show", "anttvh1v1")
            .split("state")[1]
            .split()[0]
        )
        with pytest.raises(ValueError, match="dome PC"):
            hosts.set_link("dome", False)
    assert not {"anttvh1-0", "anttvh1-1"} & _netns()


def test_only_benchmarking_addresses_and_short_tags():
    assert rehearsal_address_problem("198.19.4.2") is None
    for bad in ("192.168.1.2", "10.0.0.1", "198.20.0.1", "198.18.0.0", "robot0.lan", "::1"):
        assert rehearsal_address_problem(bad), bad
    with pytest.raises(ValueError, match="host robot0: address '10.0.0.2'"):
        VirtualHosts([("dome", "198.18.0.1"), ("robot0", "10.0.0.2")], "t")
    with pytest.raises(ValueError, match="tag"):
        VirtualHosts([("dome", "198.18.0.1")], "much-too-long")
