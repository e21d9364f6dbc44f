"""The live view of a several-host rehearsal reaches the machine's loopback through a
forwarded port (excavation_bringup.port_forward)."""

from __future__ import annotations

import socket
import threading

from helpers.view_client import free_port

from excavation_bringup.port_forward import NamespaceForward, main


def _echo_server() -> tuple[socket.socket, int]:
    server = socket.create_server(("127.0.0.1", 0))

    def serve():
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            with conn:
                while data := conn.recv(4096):
                    conn.sendall(data.upper())

    threading.Thread(target=serve, daemon=True).start()
    return server, server.getsockname()[1]


def test_bytes_go_both_ways_and_a_closed_server_closes_the_client():
    server, inner = _echo_server()
    forward = NamespaceForward([], free_port(), inner)  # no prefix: this namespace
    forward.start()
    try:
        for _ in range(2):  # each connection its own relay
            with socket.create_connection(("127.0.0.1", forward.port), timeout=30) as c:
                c.sendall(b"view")
                got = b""
                while len(got) < 4:
                    got += c.recv(4096)
                assert got == b"VIEW"
                c.shutdown(socket.SHUT_WR)  # the client is done: the server closes
                assert c.recv(4096) == b""
    finally:
        forward.stop()
        server.close()


def test_the_inner_end_refuses_a_bad_port():
    assert main(["http"]) == 2 and main(["70000"]) == 2
