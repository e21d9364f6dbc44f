"""A TCP port of this machine's loopback forwarded into a network namespace's loopback.

A rehearsal of several hosts runs the dome PC's processes, the live view among them, in a
network namespace of their own (:mod:`excavation_bringup.host_rehearsal`): the view binds
127.0.0.1 there, which Foxglove on the machine cannot reach. :class:`NamespaceForward`
listens on 127.0.0.1:PORT of the namespace it runs in and, for each connection, starts
``python -m excavation_bringup.port_forward PORT`` inside the other namespace (through the
``ip netns exec`` prefix), which connects to 127.0.0.1:PORT there and relays the bytes over
its standard input and output. Loopback to loopback: nothing leaves the machine.
"""

from __future__ import annotations

import contextlib
import functools
import socket
import subprocess
import sys
import threading
import time

CONNECT_WITHIN = 30.0
"""Seconds the inner end keeps trying to reach a server that is still starting."""
CHUNK = 65536


class NamespaceForward:
    """Forwards ``127.0.0.1:port`` here to ``127.0.0.1:port`` behind ``prefix`` (a thread).

    Args:
        prefix: The command prefix that runs a program in the other namespace
            (``ip netns exec NAME``).
        port: The port listened on here.
        inner: The port connected to there (default: ``port``).
    """

    def __init__(self, prefix: list[str], port: int, inner: int | None = None) -> None:
        self.prefix, self.port = prefix, port
        self.inner = port if inner is None else inner
        self.listener = socket.create_server(("127.0.0.1", port))
        self.listener.settimeout(0.5)
        self._stop = threading.Event()
        self._procs: list[subprocess.Popen] = []
        self._thread = threading.Thread(target=self._accept, name="port-forward", daemon=True)

    def start(self) -> None:
        """Begin accepting connections."""
        self._thread.start()

    def stop(self) -> None:
        """Stop accepting and end every relay."""
        self._stop.set()
        self._thread.join(timeout=5.0)
        self.listener.close()
        for proc in self._procs:
            if proc.poll() is None:
                proc.terminate()
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.wait(timeout=5.0)

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self.listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            command = [*self.prefix, sys.executable, "-m", __name__, str(self.inner)]
            proc = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE)
            self._procs.append(proc)
            to_proc = (conn.recv, _writer(proc.stdin), proc.stdin.close)
            to_conn = (proc.stdout.read1, conn.sendall, functools.partial(_close, conn))
            threading.Thread(target=_pump, args=to_proc, daemon=True).start()
            threading.Thread(target=_pump, args=to_conn, daemon=True).start()


def _pump(read, write, done=None) -> None:
    """Copy chunks from ``read`` to ``write`` until the end (or an error); then ``done``."""
    with contextlib.suppress(OSError, ValueError):
        while data := read(CHUNK):
            write(data)
    if done is not None:
        with contextlib.suppress(OSError, ValueError):
            done()


def _close(conn: socket.socket) -> None:
    """Shut a relayed connection both ways and close it."""
    with contextlib.suppress(OSError):
        conn.shutdown(socket.SHUT_RDWR)
    conn.close()


def _writer(out):
    """A write-and-flush of a binary stream."""

    def write(data: bytes) -> None:
        out.write(data)
        out.flush()

    return write


def relay(port: int, within: float = CONNECT_WITHIN) -> int:
    """The inner end: connect to ``127.0.0.1:port``, relay it to stdin and stdout.

    Returns 0 after the connection closed, 1 when no server answered within ``within`` s.
    """
    deadline = time.monotonic() + within
    while True:
        try:
            sock = socket.create_connection(("127.0.0.1", port), timeout=5.0)
            break
        except OSError:
            if time.monotonic() > deadline:
                print(f"port_forward: nothing listens on 127.0.0.1:{port}", file=sys.stderr)
                return 1
            time.sleep(0.2)
    sock.settimeout(None)
    # The client's bytes go on in a thread; the relay ends when the server's side closes.
    done = functools.partial(sock.shutdown, socket.SHUT_WR)  # the client is done
    threading.Thread(
        target=_pump, args=(sys.stdin.buffer.read1, sock.sendall, done), daemon=True
    ).start()
    _pump(sock.recv, _writer(sys.stdout.buffer))
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m excavation_bringup.port_forward PORT`` (the inner end)."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1 or not args[0].isdigit() or not 0 < int(args[0]) < 65536:
        print("usage: python -m excavation_bringup.port_forward PORT", file=sys.stderr)
        return 2
    return relay(int(args[0]))


if __name__ == "__main__":
    sys.exit(main())
