"""Timing profiles: every wall-clock wait, retry and deadman of a way of running, in one place.

A trial's nodes meet on handshakes (a tick waits for every word, a snapshot for its poses),
and where a handshake can fail for good they fall back on a wait. Those fallbacks depend on
how the graph runs, not on what it runs: one process whose nodes share an executor and a
clock (``composed``), a process per node on one loaded machine under the simulator's clock
(``processes``), or the dome on the wall clock (``dome``). Each fallback is a field of
:class:`TimingProfile`; :data:`PROFILES` holds the three, and the node spec functions of
:mod:`excavation_bringup.nodes` read them from there and nowhere else.
``docs/architecture.md`` ("Timing profiles") has the table with the reasons.

A field that is ``None`` leaves the node's own default (its parameter dataclass) in place.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TimingProfile:
    """The wall-clock fallbacks of one way of running a graph.

    Attributes:
        name: ``composed``, ``processes`` or ``dome``.
        deadman: Heartbeat age that stops an executor or homes a blade, s of the nodes'
            clock (``None``: the nodes' 0.5 s, the field's team deadman). As processes on
            the simulator's clock, a supervisor held up by the machine for 25 ms of wall
            time is 0.5 s of sim time at 20 x: 10 s of sim time keeps at least the field's
            0.5 s of wall time.
        blade_wait: Sim seconds the team tick waits for every blade to reach its setting
            before it takes a snapshot anyway (``None``: 2 s). Processes: the blade's path
            is a few messages between processes while the clock runs 10 x real time.
        snapshot_retry: Wall seconds before the team tick asks again for an unacknowledged
            or incomplete snapshot (``None``: 2 s). Asking because perception is merely slow
            moves the sensors' noise stream on, so processes wait longer.
        first_word_timeout: Wall seconds tick 0 waits for every controller's word
            (``None``: the team tick's 60 s; a site's ``sim.first_command_timeout`` wins).
        dynamics_command_timeout: Most wall seconds a ``dynamics`` step waits for every
            executor's ``cmd_vel`` (``None``: the node's 0.5 s).
        max_time_factor: ``dynamics`` runs at most this many times real time while robots
            move (``None``: no cap). Every node judges heartbeats on the simulator's clock,
            so a process held up for some wall time misses that many times more sim time.
        idle_time_factor: ``dynamics`` runs at most this many times real time while the
            team stands still (controllers deciding, a snapshot rendering).
        pose_timeout: Age (by its stamp) at which an executor's pose is stale and stops the
            robot, s (``None``: the executor's 0.3 s). The dome's executors close their loop
            on the localiser, whose poses arrive a frame's latency after their stamps.
        pose_wait: Wall seconds a finished laser sweep waits for the localiser's poses of
            its instant before the mapper fuses it with the poses it has.
        mount_wait: Seconds a laser scan waits for the mount state of its stamp (stamps, or
            wall time once nothing is queued) before the mapper drops it.
        counters_wait: Wall seconds a process trial waits after its last tick for every
            executor's next ``/diagnostics`` report (one per wall second).
        record_tail: Wall seconds a composed recording trial runs on after its last tick,
            so that the bag holds what is still in flight.
        recorder_tail: Wall seconds a composed lockstep recording waits for the last tick's
            state and answers to reach the bag.
    """

    name: str
    deadman: float | None = None
    blade_wait: float | None = None
    snapshot_retry: float | None = None
    first_word_timeout: float | None = None
    dynamics_command_timeout: float | None = None
    max_time_factor: float | None = None
    pose_timeout: float | None = None
    idle_time_factor: float = 10.0
    pose_wait: float = 2.0
    mount_wait: float = 10.0
    counters_wait: float = 30.0
    record_tail: float = 1.0
    recorder_tail: float = 5.0


COMPOSED = TimingProfile("composed")
"""One process, one executor, one clock: the field's deadman holds, and the poses of a frame
reach the mapper within milliseconds."""

PROCESSES = TimingProfile(
    "processes",
    deadman=10.0,
    blade_wait=60.0,
    snapshot_retry=20.0,
    dynamics_command_timeout=60.0,
    max_time_factor=20.0,
    pose_wait=30.0,
)
"""A process per node on one loaded machine under the simulator's clock (``ant-trial
--processes``, ``ant-dome up --sim``)."""

DOME = TimingProfile("dome", first_word_timeout=300.0, mount_wait=1.0, pose_timeout=0.6)
"""The dome: every node on the wall clock with the field's 0.5 s deadman; tick 0 waits up to
300 s for the words (a dome PC on a cold numba cache compiles every controller's kernels
first: over a minute each on a loaded 2-core machine, docs/benchmarks.md); a best-effort
laser, whose lost mount state is not repaired, so a scan waits 1 s for it; a localiser pose
reaches an executor a frame's latency after its stamp (median 0.12 s, at most 0.41 s in a
recorded rehearsal on 2 cores) and the next one a frame period later, so a pose is stale
after 0.6 s, not the simulator's 0.3 s (which stopped most drives of a 10 Hz camera)."""

PROFILES = {p.name: p for p in (COMPOSED, PROCESSES, DOME)}
"""The profiles by name."""
