"""The blade driver node's parameters as one frozen dataclass (no rclpy; ``config/driver.yaml``).

:class:`DriverNodeParams` holds every ROS parameter of ``ros2 run blade_driver driver``: the
backend and its port, the servo calibration, the safety timing, and the fields of
:class:`blade_driver.core.DriverParams` (the blade's own limits and force loop), which its
``check()`` validates the same way the core does.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from blade_driver.core import DriverParams
from blade_driver.protocol import ServoCalibration
from blade_driver.reconnect import Backoff
from excavation_common.params import param
from excavation_common.safety import DEADMAN_TIMEOUT

JOINT = "blade"


@dataclass(frozen=True)
class DriverNodeParams:
    """Parameters of the blade driver node (the ROS parameters of the same names)."""

    backend: str = param(
        "sim", "sim: the simulator's blade; serial: a servo board", choices=("sim", "serial")
    )
    port: str = param("/dev/ttyUSB0", "serial backend: the servo board's port")
    baudrate: int = param(115200, "serial line speed", low=1200, high=4_000_000)
    serial_timeout: float = param(0.1, "s to wait for the board's answer", low=0.001, high=10.0)
    rate: float = param(20.0, "Hz, serial backend control loop", low=1.0, high=1000.0)
    board_timeout: float = param(
        1.0,
        "serial: s without a set-point after which the board itself sends the blade home "
        "(its TIMEOUT, armed at connect: a dead driver or robot computer); 0: leave it off",
        low=0.0,
        high=60.0,
    )
    reopen_initial: float = param(
        0.5, "s before the first retry of an absent port", low=0.01, high=60.0
    )
    reopen_max: float = param(
        5.0, "s, longest wait between retries of an absent port", low=0.01, high=600.0
    )
    servo_zero_deg: float = param(90.0, "servo angle with the blade level with the wheels")
    servo_deg_per_m: float = param(600.0, "servo degrees per metre of blade travel")
    servo_min_deg: float = param(0.0, "lowest angle the board accepts")
    servo_max_deg: float = param(180.0, "highest angle the board accepts")
    joints: tuple = param((JOINT,), "order of the values on blade/commands")
    depth: float = param(0.02, "m, blade below / above the wheels for below / above")
    home: float = param(0.10, "m, blade edge when retracted")
    max_force: float = param(10.0, "N of a full blade (24 soil units)")
    position_min: float = param(-0.03, "m, lowest set-point")
    position_max: float = param(0.12, "m, highest set-point")
    max_speed: float = param(0.25, "m/s, set-point slew limit")
    push_force: float = param(6.0, "N held by the constant-force loop", read_only=False)
    kp: float = param(0.0008, "m/N, force loop", read_only=False)
    ki: float = param(0.002, "m/(N s), force loop", read_only=False)
    kd: float = param(0.0, "m s/N, force loop", read_only=False)
    trim_limit: float = param(0.008, "m, largest force-loop trim", read_only=False)
    watchdog_timeout: float = param(1.5, "s without a behaviour word: blade home", read_only=False)
    override_timeout: float = param(0.5, "s an operator set-point stays in charge", read_only=False)
    deadman: float = param(
        DEADMAN_TIMEOUT, "s without a team heartbeat: blade home", low=0.05, high=10.0
    )
    rearm_after_loss: bool = param(
        False,
        "on a robot's own computer: after a lost heartbeat (a dropped link) the blade stays "
        "home until a newer arming on /team/armed (the operator re-arms)",
    )
    safety_rate: float = param(
        50.0, "Hz at which the team state (deadman) is checked", low=10.0, high=1000.0
    )
    blade_after_motion: bool = param(
        False,
        "field (team tick): a tick's blade bits wait until drive/status of that tick has ended",
    )
    autostart: bool = param(True, "configure and activate at start (else: lifecycle services)")
    diagnostics_period: float = param(1.0, "s between diagnostics", low=0.05, high=60.0)

    def driver(self) -> DriverParams:
        """The core's parameters (validated by :class:`DriverParams`)."""
        names = [f.name for f in dataclasses.fields(DriverParams)]
        return DriverParams(**{n: getattr(self, n) for n in names})

    def calibration(self) -> ServoCalibration:
        """Blade position <-> servo angle."""
        return ServoCalibration(
            self.servo_zero_deg, self.servo_deg_per_m, self.servo_min_deg, self.servo_max_deg
        )

    def backoff(self) -> Backoff:
        """When to retry an absent port."""
        return Backoff(self.reopen_initial, max(self.reopen_initial, self.reopen_max))

    def check(self) -> None:
        """Rules across fields: the core's, and a joint named ``blade``."""
        self.driver()
        if JOINT not in self.joints:
            raise ValueError(f"joints = {list(self.joints)}: must name the {JOINT!r} joint")
