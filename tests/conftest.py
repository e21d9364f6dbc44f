"""Shared fixtures. ROS tests stay on loopback with a domain of their own."""

from __future__ import annotations

import itertools
import os
import time

import pytest

from excavation_common.middleware import use_profiles

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
use_profiles()  # what every node of the suite runs with (the tests' own nodes too)
# Under pytest-xdist (`make test` runs `-n 2`) each worker takes its own block of domains,
# handed out in order from a place its process id picks, so no two workers share one.
_WORKERS = max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))
_WORKER = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw") or 0)
_SPAN = 200 // _WORKERS
_DOMAINS = itertools.count(os.getpid() % _SPAN)


def _udp_ports() -> set[int]:
    """Local UDP ports bound on this machine (``/proc/net/udp``, ``udp6``)."""
    ports = set()
    for name in ("/proc/net/udp", "/proc/net/udp6"):
        try:
            with open(name) as f:
                lines = f.read().splitlines()[1:]
        except OSError:
            continue
        ports |= {int(line.split()[1].rsplit(":", 1)[1], 16) for line in lines if line.strip()}
    return ports


def domain_in_use(domain: int, ports: set[int] | None = None) -> bool:
    """Some DDS participant on this machine uses ``domain`` (another session's test, say).

    RTPS gives participant p of domain d the unicast port 7410 + 250 d + 2 p; a trial has a
    few dozen participants at most.
    """
    ports = _udp_ports() if ports is None else ports
    base = 7410 + 250 * domain
    return any(base + 2 * p in ports for p in range(64))


def next_domain() -> int:
    """A ROS domain id no other test of this session (or other xdist worker) uses, skipping
    domains a participant on this machine already uses (engineers share the machine)."""
    ports = _udp_ports()
    for _ in range(_SPAN):
        domain = 20 + _WORKER * _SPAN + next(_DOMAINS) % _SPAN
        if not domain_in_use(domain, ports):
            return domain
    return domain


@pytest.fixture
def ros():
    """A fresh rclpy context on its own ROS domain, with a spin-until helper."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    context = Context()
    domain = next_domain()
    rclpy.init(context=context, domain_id=domain)
    executor = SingleThreadedExecutor(context=context)

    class Ros:
        def __init__(self):
            self.context = context
            self.executor = executor
            self.domain = domain

        def add(self, node):
            executor.add_node(node)
            return node

        def spin_until(self, condition, timeout=10.0):
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline:
                if condition():
                    return True
                executor.spin_once(timeout_sec=0.05)
            return condition()

    yield Ros()
    for node in list(executor.get_nodes()):
        executor.remove_node(node)
        node.destroy_node()
    executor.shutdown()
    rclpy.try_shutdown(context=context)


@pytest.fixture
def ros_env() -> dict[str, str]:
    """Environment for a node started as a subprocess: loopback, a domain of its own."""
    return dict(
        os.environ, ROS_DOMAIN_ID=str(next_domain()), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"
    )
