"""A Foxglove WebSocket client of the live view's control surface (``/operator/*``).

What a script, a benchmark or a test needs to drive the view as Foxglove's panels do: call
a service and read its answer, or publish on a client channel (docs/operations.md, "The
live view"). Synchronous: each call sends, then reads frames until its answer comes, and
``pump`` runs the caller's event loop meanwhile (for example a ROS executor whose nodes the
view's services wait on).
"""

from __future__ import annotations

import json
import struct
import time
from collections.abc import Callable

SUBPROTOCOL = "foxglove.sdk.v1"
_CALL, _PUBLISH, _RESPONSE = 2, 1, 3  # client and server binary opcodes


class ViewClientError(RuntimeError):
    """The view did not advertise a service or answer a call in time."""


class ControlClient:
    """Calls the view's services and publishes on its client channels.

    Args:
        port: The view's port.
        pump: Called between reads while waiting (the caller's event loop).
        host: The view's address (loopback unless the view was opened up).
        within: Seconds to keep trying to connect (a view still starting).
    """

    def __init__(
        self,
        port: int,
        pump: Callable[[], object] = lambda: None,
        host: str = "127.0.0.1",
        within: float = 60.0,
    ) -> None:
        from websockets.sync.client import connect

        deadline = time.monotonic() + within
        while True:
            try:
                self.ws = connect(f"ws://{host}:{port}", subprotocols=[SUBPROTOCOL])
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                pump()
                time.sleep(0.5)
        self.pump = pump
        self.services: dict[str, int] = {}
        self.answers: dict[int, tuple[bool, object]] = {}
        self.capabilities: list[str] = []
        self.next_id = 1

    def close(self) -> None:
        """Close the connection."""
        self.ws.close()

    def _read(self, timeout: float = 0.05) -> None:
        try:
            frame = self.ws.recv(timeout=timeout)
        except TimeoutError:
            return
        if isinstance(frame, str):
            msg = json.loads(frame)
            if msg.get("op") == "serverInfo":
                self.capabilities = msg.get("capabilities", [])
            elif msg.get("op") == "advertiseServices":
                self.services.update({s["name"]: s["id"] for s in msg["services"]})
            elif msg.get("op") == "serviceCallFailure":
                self.answers[msg["callId"]] = (False, msg["message"])
            return
        if frame[0] == _RESPONSE:
            _, _, call, n = struct.unpack_from("<BIII", frame)
            self.answers[call] = (True, json.loads(frame[13 + n :]))

    def wait(self, condition: Callable[[], bool], timeout: float = 30.0) -> bool:
        """Read frames (and pump) until ``condition()``; False after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self._read()
            self.pump()
        return True

    def send(self, service: str, request: dict, timeout: float = 30.0) -> int:
        """Send a call without waiting for its answer; its call id.

        Raises:
            ViewClientError: The view advertised no ``service`` within ``timeout``.
        """
        if not self.wait(lambda: service in self.services, timeout):
            raise ViewClientError(f"the view advertises no {service} (has {self.services})")
        call, self.next_id = self.next_id, self.next_id + 1
        head = struct.pack("<BIII", _CALL, self.services[service], call, 4) + b"json"
        self.ws.send(head + json.dumps(request).encode())
        return call

    def call(self, service: str, request: dict, timeout: float = 30.0) -> tuple[bool, object]:
        """``(True, answer)`` or ``(False, the view's failure message)``.

        Raises:
            ViewClientError: No such service, or no answer within ``timeout``.
        """
        call = self.send(service, request, timeout)
        if not self.wait(lambda: call in self.answers, timeout):
            raise ViewClientError(f"{service}: no answer within {timeout} s")
        return self.answers.pop(call)

    def advertise(self, topic: str, schema_name: str) -> int:
        """Advertise a JSON client channel on ``topic``; its channel id."""
        channel, self.next_id = self.next_id, self.next_id + 1
        spec = {"id": channel, "topic": topic, "encoding": "json", "schemaName": schema_name}
        self.ws.send(json.dumps({"op": "advertise", "channels": [spec]}))
        return channel

    def publish(self, channel: int, message: dict) -> None:
        """Publish ``message`` on an advertised client channel."""
        self.ws.send(struct.pack("<BI", _PUBLISH, channel) + json.dumps(message).encode())
