"""Shared fixtures. ROS tests stay on loopback with a domain of their own."""

from __future__ import annotations

import itertools
import os
import time

import pytest

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
# Under pytest-xdist (`make test` runs `-n 2`) each worker takes its own block of domains,
# handed out in order from a place its process id picks, so no two workers share one.
_WORKERS = max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))
_WORKER = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw") or 0)
_SPAN = 200 // _WORKERS
_DOMAINS = itertools.count(os.getpid() % _SPAN)


def next_domain() -> int:
    """A ROS domain id no other test of this session (or other xdist worker) uses."""
    return 20 + _WORKER * _SPAN + next(_DOMAINS) % _SPAN


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
