"""A Foxglove WebSocket client for tests: subscribes to the live view's channels and keeps
the last message of each, decoded (protobuf from the advertised schema, or JSON)."""

from __future__ import annotations

import base64
import json
import struct
import threading
import time


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on (for a server a test starts)."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _decoder(channel: dict):
    """A function bytes -> message for a protobuf channel (from its advertised schema)."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    assert channel["encoding"] == "protobuf" and channel["schemaEncoding"] == "protobuf"
    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
    pool = descriptor_pool.DescriptorPool()
    for f in files.file:
        pool.Add(f)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))
    return cls.FromString


class Client(threading.Thread):
    """Connects, subscribes to ``topics`` and keeps the last message of each, decoded."""

    def __init__(self, port: int, topics: list[str], connect_within: float = 0.0):
        super().__init__(daemon=True)
        self.port, self.topics = port, topics
        self.connect_within = connect_within
        """Seconds to keep trying to connect (a server still starting); 0: one try."""
        self.last: dict[str, object] = {}
        self.channels: dict[str, dict] = {}
        self.error: Exception | None = None
        self.closed = False
        self.stop = threading.Event()

    def run(self):
        from websockets.exceptions import ConnectionClosed
        from websockets.sync.client import connect

        try:
            with self._connect(connect) as ws:
                subscribed = {}
                while not self.stop.is_set():
                    try:
                        frame = ws.recv(timeout=0.5)
                    except TimeoutError:
                        continue
                    if isinstance(frame, str):
                        msg = json.loads(frame)
                        if msg.get("op") == "advertise":
                            new = []
                            for ch in msg["channels"]:
                                self.channels[ch["topic"]] = ch
                                if (
                                    ch["topic"] in self.topics
                                    and ch["topic"] not in subscribed.values()
                                ):
                                    sub_id = len(subscribed) + 1
                                    subscribed[sub_id] = ch["topic"]
                                    new.append({"id": sub_id, "channelId": ch["id"]})
                            if new:
                                ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))
                        continue
                    opcode, sub_id, _ = struct.unpack_from("<BIQ", frame)
                    if opcode == 1 and sub_id in subscribed:
                        topic = subscribed[sub_id]
                        payload = frame[13:]
                        ch = self.channels[topic]
                        self.last[topic] = (
                            json.loads(payload)
                            if ch["encoding"] == "json"
                            else _decoder(ch)(payload)
                        )
        except ConnectionClosed:
            self.closed = True  # the server stopped (the trial ended): not an error
        except Exception as exc:  # reported to the test
            self.error = exc

    def _connect(self, connect):
        deadline = time.monotonic() + self.connect_within
        while True:
            try:
                return connect(f"ws://127.0.0.1:{self.port}", subprotocols=["foxglove.sdk.v1"])
            except Exception:  # noqa: BLE001 - refused, reset or cut mid-handshake: again
                if time.monotonic() > deadline or self.stop.is_set():
                    raise
                time.sleep(0.5)


class ControlClient:
    """A Foxglove WebSocket client that calls the view's services and publishes on it.

    Synchronous: each call sends and reads frames until its answer comes (``pump`` runs the
    caller's event loop meanwhile, e.g. the test's ROS executor, which the view's services
    need to get the supervisor's answers).
    """

    def __init__(self, port: int, pump=lambda: None, host: str = "127.0.0.1", within=60.0):
        from websockets.sync.client import connect

        deadline = time.monotonic() + within  # a server still starting: tried again
        while True:
            try:
                self.ws = connect(f"ws://{host}:{port}", subprotocols=["foxglove.sdk.v1"])
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)
        self.pump = pump
        self.services: dict[str, int] = {}
        self.answers: dict[int, tuple[bool, object]] = {}
        self.capabilities: list[str] = []
        self.next_id = 1

    def close(self) -> None:
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
        if frame[0] == 3:  # service call response
            _, _, call, n = struct.unpack_from("<BIII", frame)
            self.answers[call] = (True, json.loads(frame[13 + n :]))

    def wait(self, condition, timeout: float = 30.0) -> bool:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self._read()
            self.pump()
        return True

    def call(self, service: str, request: dict, timeout: float = 30.0):
        """``(True, answer)`` or ``(False, failure message)``; raises on no answer."""
        assert self.wait(lambda: service in self.services, timeout), self.services
        call, self.next_id = self.next_id, self.next_id + 1
        payload = json.dumps(request).encode()
        head = struct.pack("<BIII", 2, self.services[service], call, 4) + b"json"
        self.ws.send(head + payload)
        assert self.wait(lambda: call in self.answers, timeout), f"{service}: no answer"
        return self.answers.pop(call)

    def advertise(self, topic: str, schema_name: str) -> int:
        channel, self.next_id = self.next_id, self.next_id + 1
        spec = {"id": channel, "topic": topic, "encoding": "json", "schemaName": schema_name}
        self.ws.send(json.dumps({"op": "advertise", "channels": [spec]}))
        return channel

    def publish(self, channel: int, message: dict) -> None:
        self.ws.send(struct.pack("<BI", 1, channel) + json.dumps(message).encode())
