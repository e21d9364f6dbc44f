"""The ``serial`` backend: the blade driver talking to a servo board over a serial port.

Uses pyserial. One request, one answer (see :mod:`blade_driver.protocol`); a missing, garbled
or refused answer raises :class:`~blade_driver.errors.BoardError` with the port and the line,
which the node reports on ``/diagnostics`` before it tries again on the next control step. A
port that cannot be opened, or whose I/O fails (the board was unplugged), raises
:class:`~blade_driver.errors.PortError`: the node closes it and reopens it with back-off
(:mod:`blade_driver.reconnect`).
"""

from __future__ import annotations

import termios

import serial

from blade_driver.errors import BoardError, PortError
from blade_driver.protocol import ServoCalibration, decode, encode


class SerialBackend:
    """A servo board on a serial port.

    Args:
        port: Device path (``/dev/ttyUSB0``, or a pseudo-terminal in tests).
        baudrate: Line speed (the board's firmware uses 115200).
        timeout: Seconds to wait for an answer.
        calibration: Blade position to servo angle.

    Raises:
        PortError: The port cannot be opened.
    """

    def __init__(
        self,
        port: str,
        baudrate: int = 115200,
        timeout: float = 0.1,
        calibration: ServoCalibration | None = None,
    ) -> None:
        self.port = port
        self.calibration = calibration or ServoCalibration()
        try:
            self._serial = serial.Serial(port, baudrate=baudrate, timeout=timeout)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise PortError(f"{port}: cannot open the servo board's port: {exc}") from exc

    def _request(self, *fields: object) -> list[str]:
        try:
            self._serial.reset_input_buffer()
            self._serial.write(encode(*fields))
            line = self._serial.readline()
        except (serial.SerialException, OSError, termios.error) as exc:  # termios: unplugged
            raise PortError(f"{self.port}: serial I/O failed: {exc}") from exc
        reply = decode(line, self.port)
        if reply and reply[0] == "ERR":
            raise BoardError(f"{self.port}: board refused {fields[0]}: {' '.join(reply[1:])}")
        return reply

    def ping(self) -> str:
        """The board's firmware name."""
        reply = self._request("PING")
        if len(reply) < 2 or reply[0] != "PONG":
            raise BoardError(f"{self.port}: expected 'PONG <firmware>', got {reply}")
        return " ".join(reply[1:])

    def set_position(self, position: float) -> float:
        """Command the blade to ``position`` (m); returns the angle the board acknowledged."""
        angle = f"{self.calibration.angle(position):.2f}"
        reply = self._request("SET", angle)
        if reply != ["ACK", "SET", angle]:
            raise BoardError(f"{self.port}: expected 'ACK SET {angle}', got {reply}")
        return float(angle)

    def set_timeout(self, seconds: float) -> int:
        """Arm the board's set-point timeout (``TIMEOUT <ms>``; 0 disarms it).

        Returns the milliseconds acknowledged. Raises :class:`BoardError` when the board
        refuses it (firmware without a timeout answers ``ERR 4``).
        """
        ms = max(0, int(round(seconds * 1000)))
        reply = self._request("TIMEOUT", ms)
        if reply != ["ACK", "TIMEOUT", str(ms)]:
            raise BoardError(f"{self.port}: expected 'ACK TIMEOUT {ms}', got {reply}")
        return ms

    def read(self) -> tuple[float, float]:
        """``(position m, force N)`` measured by the board."""
        reply = self._request("READ")
        if len(reply) != 3 or reply[0] != "STATE":
            raise BoardError(f"{self.port}: expected 'STATE <deg> <N>', got {reply}")
        try:
            angle, force = float(reply[1]), float(reply[2])
        except ValueError as exc:
            raise BoardError(f"{self.port}: STATE fields are not numbers: {reply}") from exc
        if angle != angle or force != force:
            raise BoardError(f"{self.port}: STATE has NaN: {reply}")
        return self.calibration.position(angle), force

    def close(self) -> None:
        """Close the port (never raises: the device may be gone already)."""
        try:
            self._serial.close()
        except (serial.SerialException, OSError):
            pass
