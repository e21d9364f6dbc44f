"""Shared fixtures. ROS tests stay on loopback with a domain of their own.

A test takes its ROS domain from a fixture: ``domain`` (one fresh id), ``domains`` (a
function handing out fresh ids, ``domains(n)`` the first of ``n`` consecutive ones; session
scoped, so a fixture of any scope can use it), or ``ros`` / ``ros_env`` (which take theirs
from ``domains``). Shared helpers live in ``tests/helpers`` (``from helpers.worlds import
...``); the ``camera`` fixture is :func:`helpers.cameras.camera`, registered here.
"""

from __future__ import annotations

import itertools
import os
import time

import pytest
from helpers.cameras import camera  # noqa: F401 - the fixture, for every test module

from excavation_common.middleware import use_profiles

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
use_profiles()  # what every node of the suite runs with (the tests' own nodes too)
# ROS domains 1-100 only: from domain 102 up the RTPS ports (7400 + 250 d + offsets) fall in
# Linux's ephemeral port range (32768-60999), where any outgoing socket may take one first.
# Under pytest-xdist (`make test` runs `-n 2`) each worker takes its own block of them
# (gw0 1-50, gw1 51-100), handed out in turn from a place its process id picks, so that two
# test sessions on one machine start apart (and `domain_in_use` skips what another holds).
DOMAIN_RANGE = range(1, 101)
_WORKERS = max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))
_WORKER = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw") or 0)
_SPAN = len(DOMAIN_RANGE) // _WORKERS
_BLOCK = range(DOMAIN_RANGE.start + _WORKER * _SPAN, DOMAIN_RANGE.start + (_WORKER + 1) * _SPAN)
_TURN = itertools.count(os.getpid() % _SPAN)


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


def _take_domains(count: int) -> int:
    """The first of ``count`` consecutive ROS domains of this worker's block, all free.

    Takes them all: no later call of this session (or another xdist worker) hands them out
    again before the block comes round. Skips domains a participant on this machine already
    uses (engineers share the machine). Raises ``RuntimeError`` when the block has no such run.
    """
    if not 1 <= count <= _SPAN:
        raise ValueError(f"{count} domains asked, a worker's block holds {_SPAN}")
    ports = _udp_ports()
    for _ in range(_SPAN):
        first = next(_TURN) % _SPAN
        if first + count > _SPAN:
            continue
        domains = [_BLOCK[first + i] for i in range(count)]
        if not any(domain_in_use(d, ports) for d in domains):
            for _ in range(count - 1):
                next(_TURN)
            return domains[0]
    raise RuntimeError(f"no {count} free consecutive ROS domains in {_BLOCK}")


@pytest.fixture(scope="session")
def domains():
    """A function handing out fresh ROS domains of this worker's block.

    ``domains()`` is one id, ``domains(n)`` the first of ``n`` consecutive ones (all taken);
    every call gives ids no other call of this session gives (see :func:`_take_domains`).
    Session scoped: fixtures of any scope may use it.
    """

    def take(count: int = 1) -> int:
        return _take_domains(count)

    return take


@pytest.fixture
def domain(domains) -> int:
    """A fresh ROS domain id (1-100) of this worker's block, for this test alone."""
    return domains()


@pytest.fixture
def ros(domains):
    """A fresh rclpy context on its own ROS domain, with a spin-until helper."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    context = Context()
    domain = domains()
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
def ros_env(domains) -> dict[str, str]:
    """Environment for a node started as a subprocess: loopback, a domain of its own."""
    return dict(os.environ, ROS_DOMAIN_ID=str(domains()), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
