"""A Foxglove WebSocket client for tests: subscribes to the live view's channels and keeps
the last message of each, decoded (protobuf from the advertised schema, or JSON). The
control surface's client is the package's own (``excavation_bringup.view_client``)."""

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
