"""The fault matrix (docs/reliability.md): each row's fault injected into a process trial.

Every test starts a lockstep trial with each node its own process (``tests/faults.py``),
injects one fault (SIGKILL and restart of a node, a stalled or slowed sensor, a clock
jump, a full disk, an interrupted checkpoint) and checks what the system does, what a user
sees (``/diagnostics``, exit codes, logs) and what is lost.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from faults import FaultTrial
from helpers.limits import limited
from helpers.trials import offline

from excavation_bags.cli import main as bag_main
from excavation_bags.reader import open_bag
from excavation_bringup.trial import run_trial

# wall-clock faults: run alone, in make test-system
pytestmark = [pytest.mark.serial, pytest.mark.system]

SIM = "/sim"


def controller(k: int) -> str:
    """Diagnostics name of robot k's controller."""
    return f"/robot_{k}/controller"


def blade_driver(k: int) -> str:
    """Diagnostics name of robot k's blade driver."""
    return f"/robot_{k}/blade_driver"


IDLE = re.compile(r"tick (\d+): no command from robots \[([\d, ]+)\]; they idle")
"""``/sim``'s report of a tick in which robots' words did not come (they idled)."""


def idle_reports(messages: list[str]) -> list[tuple[int, str]]:
    """``(tick, robot)`` of every robot named in an :data:`IDLE` report, in order."""
    found = [IDLE.fullmatch(m) for m in messages]
    return [(int(f.group(1)), k) for f in found if f for k in f.group(2).split(", ")]


def sim_messages(trial: FaultTrial, result: dict, timeout: float = 30.0) -> list[str]:
    """``/sim``'s messages once the watcher has heard a report of every tick ``result``
    counts as missed (it may hear the last after the simulator ended), or ``timeout`` s."""

    def heard() -> bool:
        robots = [k for _, k in idle_reports(trial.messages(SIM))]
        return all(robots.count(k) >= n for k, n in result["missed"].items())

    with contextlib.suppress(TimeoutError):
        trial.wait_for(heard, timeout=timeout, what="an idle report of every missed tick")
    return trial.messages(SIM)


def losses_reported(result: dict, sim: list[str]) -> dict[str, list[int]]:
    """The ticks ``/sim`` reported each robot idle in, checked against the trial's result.

    Every tick a robot's word did not come, the simulator says so (:data:`IDLE`) and counts
    it in ``missed``: per robot, the reported ticks are distinct and as many as ``missed``
    says, and the robot's applied word in each is 0. The trial ran to its end however many
    were lost (a fitness after every tick).
    """
    steps = len(result["commands"])
    assert len(result["trace"]) == steps + 1 and result["fitness"] == result["trace"][-1]
    lost: dict[str, list[int]] = {k: [] for k in result["missed"]}
    for tick, k in idle_reports(sim):
        lost[k].append(tick)
    for k, ticks in lost.items():
        assert len(set(ticks)) == len(ticks) == result["missed"][k], (k, ticks, result["missed"])
        assert all(result["commands"][t][int(k)] == 0 for t in ticks), (k, ticks)
    return lost


def kill_and_restart(trial: FaultTrial, name: str, at: int = 5, down: int = 3) -> tuple[int, int]:
    """SIGKILL ``name`` at tick ``at``, restart it ``down`` ticks later: (killed, restarted)."""
    killed = trial.wait_tick(at)
    assert trial.kill(name) == -9
    restarted = trial.wait_tick(killed + down)
    trial.restart(name)
    return killed, restarted


# --- SIGKILL + restart, truth perception ---------------------------------------------------


def test_server_killed_and_restarted(tmp_path, domain):
    """The blueprint is latched: controllers keep it, the trial is not disturbed at all."""
    steps, seed = 30, 3
    # a long command timeout: starting the new server's process loads the machine, and no
    # robot may miss a tick in this row (a late word is waited for, not missed)
    with FaultTrial(tmp_path, domain, steps=steps, seed=seed, command_timeout=30.0) as trial:
        kill_and_restart(trial, "server")
        result = trial.result()
    heights, fitness = offline("hand-coded", 2, steps, seed)
    assert result["missed"] == {"0": 0, "1": 0}
    assert result["fitness"] == fitness and np.array_equal(result["heights"], heights)


def test_controller_killed_and_restarted(tmp_path, domain):
    """The robot idles (reported), its blade goes home, the restarted controller rejoins."""
    with FaultTrial(tmp_path, domain, steps=30) as trial:
        killed, restarted = kill_and_restart(trial, "controller_1")
        result = trial.result()
        sim = trial.messages(SIM)
        driver = trial.messages(blade_driver(1), since_tick=killed)
        untouched = trial.log("controller_0")[-3000:], trial.messages(controller(0))[-10:]
    missed = result["missed"]
    assert missed["0"] == 0, untouched  # what the other robot's controller said, if not
    assert restarted - killed - 1 <= missed["1"] <= restarted - killed + 2
    assert any("no command from robots [1]" in m for m in sim)
    assert any(m.startswith("watchdog") for m in driver)  # blade home while orphaned
    assert result["commands"][-1][1] != 0 or result["commands"][-2][1] != 0  # acting again


def test_blade_driver_killed_and_restarted(tmp_path, domain):
    """The robot's blade is held and the robot idles (no joint state), then rejoins."""
    # 200 ticks (some 10 s undisturbed): a rehearsal's watcher heard tick 5 so late that the
    # kill landed after the last of 30 ticks, and nothing was missed.
    with FaultTrial(tmp_path, domain, steps=200) as trial:
        kill_and_restart(trial, "blade_driver_1")
        result = trial.result()
        sim = sim_messages(trial, result)
    assert result["missed_blade_setpoints"]["0"] == 0 and result["missed"]["0"] == 0
    # At least a tick each (the ticks between kill and restart are the watcher's, which may
    # hear the simulator late, so they bound nothing exactly).
    assert result["missed_blade_setpoints"]["1"] >= 1
    assert result["missed"]["1"] >= 1  # no blade state: no decision
    assert any("no blade set-point from robots [1]" in m for m in sim)
    # What a user sees of the idling (the row's "no command from robots [1]"), once per tick
    # robot 1 missed; the controller may or may not say "holding still" in between (it
    # waits for the joint state of a tick its driver never answers), so that is not asserted.
    losses_reported(result, sim)
    assert result["commands"][-1][1] != 0 or result["commands"][-2][1] != 0


@pytest.mark.parametrize("blade_driver", [False, True], ids=["no-driver", "blade-driver"])
def test_simulator_killed_and_restarted(tmp_path, domain, blade_driver):
    """A restarted simulator starts the trial again from tick 0: sim time jumps back.

    The controllers (and blade drivers) see every input go back in time together and follow
    the new clock (a new trial); the new run ends as an undisturbed trial would. The test
    holds the team (``/supervisor/pause``) until the watcher hears the simulator and again
    around the kill, so that a fast machine cannot end the trial before the kill lands.
    """
    steps, seed = 300, 3
    with FaultTrial(
        tmp_path, domain, steps=steps, seed=seed, blade_driver=blade_driver, start=False
    ) as trial:
        for name in trial.processes.commands:
            if name != "sim":
                trial.processes.start(name)
        trial.call("/supervisor/pause")
        trial.processes.start("sim")
        trial.wait_for(lambda: trial.statuses(SIM), what="the watcher hears the simulator")
        trial.call("/supervisor/resume")
        trial.wait_tick(12)
        trial.call("/supervisor/pause")
        assert not trial.processes.finished and trial.tick < steps - 50
        assert trial.kill("sim") == -9
        trial.wait_seconds(2.0)
        trial.restart("sim")
        trial.call("/supervisor/resume")
        result = trial.result()
        logs = {name: trial.log(name) for name in trial.processes.commands}
    # Time went back: every controller (and driver) took the new clock as a new trial. (The
    # watcher's own /clock subscription may match the new simulator only after its first
    # ticks, so what the nodes say is the evidence, not the ticks the watcher heard.)
    for k in range(2):
        assert "went back in time" in logs[f"controller_{k}"]
        if blade_driver:
            assert "sim time went back" in logs[f"blade_driver_{k}"]
    assert len(result["trace"]) == steps + 1  # the new run is a whole trial
    assert sum(result["missed"].values()) == 0
    heights, fitness = offline("hand-coded", 2, steps, seed)
    assert result["fitness"] == fitness and np.array_equal(result["heights"], heights)


def test_supervisor_killed_and_restarted(tmp_path, domain):
    """No heartbeat: blades home, the simulator holds the tick; the restart resumes the trial.

    The trial's supervisor arms at start (``arm_at_start``, an unattended trial), so its
    restart resumes by itself; an operator's supervisor starts disarmed and waits for
    ``ant-operator arm`` (tests/test_trial_oversight.py). A held tick keeps its words, so the
    trial ends as an undisturbed one.
    """
    # Long enough that the trial cannot end before the deadman stops it (truth perception
    # runs some 20 ticks a second, and the watcher may hear its first tick late).
    steps, seed = 200, 3
    with FaultTrial(tmp_path, domain, steps=steps, seed=seed) as trial:
        assert trial.wait_tick(5) < steps // 2
        killed = time.monotonic()
        assert trial.kill("supervisor") == -9

        def since_kill():
            """The simulator's statuses heard after the kill: (its tick, its team state)."""
            return [
                (int(st.values["tick"]), st.values["team"])
                for st in trial.statuses(SIM)
                if st.wall > killed and "team" in st.values
            ]

        # The simulator's own tick and team state, not the watcher's /clock (which a loaded
        # test process hears late) nor a hold before the kill (a heartbeat late at start).
        trial.wait_for(
            lambda: any(team.startswith("heartbeat lost") for _, team in since_kill()),
            what="the simulator holds",
        )
        trial.wait_seconds(3.0)
        after = since_kill()
        held = max(tick for tick, team in after if team.startswith("heartbeat lost"))
        assert after[-1][1].startswith("heartbeat lost"), after[-5:]  # still held 3 s later
        assert max(tick for tick, _ in after) <= held + 1, after  # no tick stepped since
        homed = [
            k
            for k in range(2)
            if any("hold: heartbeat lost" in m for m in trial.messages(blade_driver(k)))
        ]
        trial.restart("supervisor")
        result = trial.result()
        resumed = trial.messages(SIM, since_tick=held)
    assert homed == [0, 1]  # every blade went home by the deadman
    assert any(re.fullmatch(r"tick \d+: armed", m) for m in resumed), resumed  # resumed
    assert result["missed"] == {"0": 0, "1": 0} and result["holds"] >= 1
    heights, fitness = offline("hand-coded", 2, steps, seed)
    assert result["fitness"] == fitness and np.array_equal(result["heights"], heights)


def recorded_ticks(bag) -> list[int]:
    """Sim-time seconds of every ``/clock`` message in a bag."""
    return [bag.decode("/clock", raw).clock.sec for _, _, raw in bag.messages(["/clock"])]


def _missed_lines(sim_log: str) -> str:
    """The simulator's reports of ticks without a robot's word (which tick, which robot)."""
    return "\n".join(line for line in sim_log.splitlines() if "no command from" in line)


def test_recorder_killed_and_restarted(tmp_path, domain, capsys):
    """The killed bag is truncated and recoverable; a restart records into a new bag.

    The trial runs on while no recorder runs; then the test pauses the team until the new
    recorder is up (a fast trial would otherwise end before a recorder process starts on a
    loaded machine) and resumes it.
    """
    first, second = tmp_path / "bag", tmp_path / "bag2"
    steps = 300
    with FaultTrial(tmp_path, domain, steps=steps, record=str(first)) as trial:
        trial.wait_tick(30)
        assert trial.kill("recorder") == -9
        # Ticks go by with no recorder: all of them are lost (the watcher may lag the
        # recorder's last tick by one or two, hence three).
        unrecorded = trial.wait_tick(trial.tick + 3)
        trial.call("/supervisor/pause")
        command = [*trial.processes.commands["recorder"]]
        trial.restart("recorder")  # the same directory: refused, exit code 2
        assert trial.processes.procs.pop("recorder").wait(timeout=120) == 2
        assert "exists; bags are not overwritten" in trial.log("recorder")
        command[command.index("--out") + 1] = str(second)
        restarted = time.monotonic()
        trial.restart("recorder", command)
        trial.wait_for(
            lambda: any(
                s.wall > restarted and int(s.values.get("messages", 0)) > 0
                for s in trial.statuses("/bag_recorder")
            ),
            what="the new recorder records",
        )
        trial.wait_seconds(1.0)  # every topic found (it looks every 0.1 s)
        trial.call("/supervisor/resume")
        result = trial.result()
        sim_log = trial.log("sim")
    assert sum(result["missed"].values()) == 0, _missed_lines(sim_log)  # the trial did not notice
    assert open_bag(first).truncated
    assert bag_main(["recover", str(first), "--out", str(tmp_path / "fixed")]) == 0
    assert "was truncated" in capsys.readouterr().out
    fixed, new = open_bag(tmp_path / "fixed"), open_bag(second)
    before, after = recorded_ticks(fixed), recorded_ticks(new)
    assert before and after, (before, after)
    assert not fixed.truncated and before == list(range(before[0], before[0] + len(before)))
    assert before[-1] < unrecorded  # at most the last flush period is lost before the kill
    print(
        f"recorder kill near tick {unrecorded - 3}: the bag ends at tick {before[-1]}, the "
        f"new one starts at tick {after[0]}"
    )
    assert after[-1] == steps and after == list(range(after[0], steps + 1))
    assert after[0] > unrecorded > before[-1]  # the gap while no recorder ran is lost
    assert "/blueprint/zones" in new.topics  # latched: recorded again by the new bag


def test_recorder_disk_full(tmp_path, domain, capsys):
    """Writes fail (RLIMIT_FSIZE): one error line, the trial goes on, the bag is recoverable."""
    bag = tmp_path / "bag"
    with FaultTrial(tmp_path, domain, steps=200, record=str(bag), start=False) as trial:
        for name, command in trial.processes.commands.items():
            # the limit set in the recorder's own process (no preexec_fn in this threaded one)
            small_disk = limited(command, FSIZE=300_000) if name == "recorder" else None
            trial.processes.start(name, small_disk)
        code = trial.processes.procs["recorder"].wait(timeout=300)  # the disk fills up
        del trial.processes.procs["recorder"]
        stopped = trial.tick
        result = trial.result()
        log = trial.log("recorder")
        sim_log = trial.log("sim")
    assert sum(result["missed"].values()) == 0, _missed_lines(sim_log)  # the trial did not notice
    assert stopped < 200  # the recorder stopped mid-trial
    assert code == 2 and "ant-bag: error: [Errno 27] File too large" in log
    assert "Traceback" not in log
    assert bag.joinpath("bag.mcap").stat().st_size <= 300_000
    partial = open_bag(bag)
    assert partial.truncated and partial.message_count > 0
    assert bag_main(["recover", str(bag), "--out", str(tmp_path / "fixed")]) == 0
    fixed = open_bag(tmp_path / "fixed")
    ticks = recorded_ticks(fixed)
    assert not fixed.truncated and ticks == list(range(len(ticks)))


# --- full perception: localizer, mapper, camera and laser -----------------------------------

FULL = {"perception": "full", "command_timeout": 5.0, "steps": 30}


@pytest.fixture(scope="module")
def full_reference(domains):
    """Fitness of the undisturbed full-perception trial (composed: quicker, the same)."""
    return run_trial(
        "hand-coded",
        2,
        FULL["steps"],
        3,
        "default:1",
        domain=domains(),
        command_timeout=30.0,
        perception="full",
    ).fitness


def test_localizer_killed_and_restarted(tmp_path, domain):
    """No poses: every robot idles (reported); the restarted localizer finds them again."""
    with FaultTrial(tmp_path, domain, **FULL) as trial:
        killed = trial.wait_tick(5)
        assert trial.kill("localizer") == -9
        restarted = trial.wait_tick(killed + 1)  # at least one tick times out
        trial.restart("localizer")
        result = trial.result()
        sim = trial.messages(SIM)

        def seen() -> bool:  # the watcher may hear the new localizer late (as the mapper)
            return "seen" in trial.messages("/localizer: robot_0", since_tick=restarted)

        trial.wait_for(seen, timeout=60.0, what="robot 0 seen after the restart")
    assert restarted > killed
    # Both idle while no poses come. Seen once on a machine so loaded that the team was held
    # 94 times (heartbeat gaps): robot 1 idled one tick more than robot 0 (cause not found).
    assert result["missed"]["0"] >= 1 and abs(result["missed"]["0"] - result["missed"]["1"]) <= 1
    assert any("no command from robots [0, 1]" in m for m in sim)
    assert result["missed"]["0"] <= restarted - killed + 2  # acting again after the restart


def test_mapper_killed_and_restarted(tmp_path, domain):
    """No height map: every robot idles; the restarted mapper's first map is right except
    under the robots (its prior: level ground)."""
    with FaultTrial(tmp_path, domain, **FULL) as trial:
        killed = trial.wait_tick(5)
        assert trial.kill("mapper") == -9
        restarted = trial.wait_tick(killed + 1)  # at least one tick times out
        trial.restart("mapper")
        result = trial.result()
        # The watcher may match the new mapper later than the controllers do (CI once read
        # the maps before it had); the map is latched, so a late match still delivers one.
        after = lambda: any(k[0] > restarted for k in list(trial.watcher.maps["mapped"]))  # noqa: E731
        try:
            trial.wait_for(after, timeout=60.0, what="a height map after the restart")
        except TimeoutError as e:
            raise AssertionError(f"{e}; {result['missed']=}\n{trial.log('mapper')[-3000:]}") from e
        maps = trial.watcher.maps
        sim = trial.messages(SIM)
    assert restarted > killed and result["missed"]["0"] >= 1
    assert any("no command from robots [0, 1]" in m for m in sim)
    stamps = sorted(k for k in maps["mapped"] if k[0] > restarted)
    first = stamps[0]
    wrong = np.abs(maps["mapped"][first] - maps["truth"][first]) > 0.025  # half a soil unit
    print(f"mapper restart: {int(wrong.sum())} cells wrong in the first map (tick {first[0]})")
    assert wrong.sum() <= 4 * 2  # at most the cells under the two robots
    assert result["missed"]["0"] <= restarted - killed + 2


@pytest.mark.parametrize(
    ("knob", "seconds", "timeout", "loses_ticks"),
    [
        ("paused", 1.0, 30.0, False),  # a 1 s stall is shorter than the tick timeout
        ("paused", 10.0, 5.0, True),  # a 10 s stall is longer: ticks time out
        ("laser_paused", 10.0, 5.0, True),
    ],
    ids=["camera-1s", "camera-10s", "laser-10s"],
)
def test_sensor_stalls(tmp_path, domain, full_reference, knob, seconds, timeout, loses_ticks):
    """Frames or sweeps stop, then resume with the latest truth."""
    with FaultTrial(tmp_path, domain, **{**FULL, "command_timeout": timeout}) as trial:
        trial.wait_tick(5)
        trial.set_params("/sensors", **{knob: True})
        stalled = trial.tick
        trial.wait_seconds(seconds)
        trial.set_params("/sensors", **{knob: False})
        result = trial.result()
        sim = sim_messages(trial, result)
    missed = result["missed"]
    print(
        f"{knob} for {seconds} s: missed {missed}, fitness {result['fitness']} "
        f"(undisturbed {full_reference})"
    )
    losses_reported(result, sim)  # whatever was lost: reported tick by tick, the trial whole
    if loses_ticks:
        # Both robots wait for the same frame or sweep, so the stall times out both robots'
        # ticks together. The tick in which the sensor comes back may time out between the
        # two robots' answers (one word in, the other late): at most one tick apart.
        together = [m for m in sim if "no command from robots [0, 1]" in m]
        alone = [m for m in sim if re.search(r"no command from robots \[[01]\]", m)]
        assert together and len(alone) <= 1, sim
        assert min(missed.values()) >= 1 and abs(missed["0"] - missed["1"]) <= 1
        assert max(missed.values()) <= seconds / timeout + 2
    else:
        # Finding (docs/reliability.md): a stall shorter than the tick timeout should lose
        # nothing, and mostly does; one CI rehearsal lost one tick for both robots (with the
        # process trials' 30 s pose_wait, so not the mapper fusing stale poses; cause not
        # found). At most that one tick:
        assert missed["0"] <= 1 and missed["1"] <= 1, sim
        if missed == {"0": 0, "1": 0}:
            assert result["fitness"] == full_reference  # nothing lost at all
    assert stalled >= 5


def test_camera_at_5_hz(tmp_path, domain, full_reference):
    """A slow camera slows the lockstep trial down; nothing is lost."""
    with FaultTrial(tmp_path, domain, **{**FULL, "command_timeout": 30.0}) as trial:
        trial.set_params("/sensors", timeout=120.0, frame_period=0.2)
        result = trial.result()
        sim = sim_messages(trial, result)
    missed = result["missed"]
    # Seen once on a machine at load 40: the whole team lost one tick ({'0': 1, '1': 1}),
    # most likely tick 0's frame sent before the localizer was matched (docs/reliability.md,
    # "Fixed in the last round"). Both robots, at most once; nothing else may be lost.
    assert missed["0"] == missed["1"] <= 1, missed
    lost = losses_reported(result, sim)
    if missed == {"0": 0, "1": 0}:
        assert result["fitness"] == full_reference
    else:  # the whole team lost the same tick (one report naming both robots)
        assert lost["0"] == lost["1"], lost


# --- evolution: SIGKILL during checkpoint writes ---------------------------------------------

EVOLVE = [
    "--quiet",
    "--population",
    "6",
    "--generations",
    "30",
    "--scenarios",
    "2",
    "--steps",
    "30",
    "--checkpoint-every",
    "1",
    "--workers",
    "1",
    "--seed",
    "4",
]

KILL_IN_WRITE = """
import os, signal, sys
import excavation_common.files as files
import ant_evolution.loop as loop
n = int(sys.argv.pop(1))
real = files.write_text_atomic
calls = [0]
def dying(path, text):
    calls[0] += 1
    if calls[0] == n:  # half the temporary file written, then SIGKILL
        fd = os.open(os.path.join(os.path.dirname(path), "." + os.path.basename(path) + ".x.tmp"),
                     os.O_WRONLY | os.O_CREAT)
        os.write(fd, text[: len(text) // 2].encode())
        os.kill(os.getpid(), signal.SIGKILL)
    return real(path, text)
loop.write_text_atomic = dying  # every output of a run is written by the one loop
from ant_evolution.cli_evolve import main
sys.exit(main())
"""


def evolve_outputs(out) -> dict:
    """What must not depend on interruptions: checkpoint (less timings), best, history."""
    ck = json.loads((out / "checkpoint.json").read_text())
    for row in ck["history"]:
        row.pop("seconds")
    history = [",".join(line.split(",")[:-1]) for line in (out / "history.csv").open()]
    return {"checkpoint": ck, "best": (out / "best.json").read_text(), "history": history}


def test_evolve_killed_during_checkpoint_writes(tmp_path):
    """SIGKILL in the middle of writes (and at random moments); --resume ends identical."""
    straight = tmp_path / "straight"
    cmd = [sys.executable, "-m", "ant_evolution.cli_evolve"]
    subprocess.run([*cmd, "--out", str(straight), *EVOLVE], check=True, timeout=600)
    out = tmp_path / "killed"
    rng = np.random.default_rng(7)
    kills = 0
    for attempt in range(40):
        resume = ["--resume"] if (out / "checkpoint.json").exists() else []
        args = ["--out", str(out), *resume, *EVOLVE]
        # the first four are killed inside a write (a run has dozens, so each kill lands);
        # then random moments too, which a fast machine may outrun
        if attempt < 4 or attempt % 2 == 0:  # killed inside the n-th atomic write
            n = int(rng.integers(1, 9))
            proc = subprocess.run(
                [sys.executable, "-c", KILL_IN_WRITE, str(n), *args], timeout=600, check=False
            )
        else:  # killed at a random moment
            p = subprocess.Popen([*cmd, *args])
            try:
                p.wait(timeout=float(rng.uniform(2.0, 10.0)))
            except subprocess.TimeoutExpired:
                os.kill(p.pid, signal.SIGKILL)
                p.wait()
            proc = p
        if proc.returncode == 0:
            break
        assert proc.returncode == -9
        kills += 1
    else:
        pytest.fail("the run never finished")
    assert kills >= 4
    assert evolve_outputs(out) == evolve_outputs(straight)


# --- the continuous trial (ant-trial --drive continuous --processes) ---------------------------
#
# Every node its own process (excavation_bringup.launch.ProcessLauncher): the fault is a SIGKILL
# of the node's process and its restart with the same command line.

MOTION_LIMIT = 15.0
"""The team tick leaves a robot out after ``motion_limit`` s of sim time (120 by default);
these rows wait 15 s (a primitive takes a few)."""


def executor(k: int) -> str:
    """Diagnostics name of robot k's drive executor."""
    return f"/robot_{k}/executor"


def continuous_fault_trial(tmp_path, domain: int, robots: int, steps: int) -> FaultTrial:
    """A continuous process trial (truth perception) whose team tick waits 15 s for a robot."""
    trial = FaultTrial(tmp_path, domain, robots=robots, steps=steps, continuous=True, start=False)
    trial.processes.set_params("team_tick", motion_limit=MOTION_LIMIT)
    trial.processes.start()
    return trial


def test_drive_executor_killed_and_restarted(tmp_path, domain):
    """Robot 1's executor process is SIGKILLed: its wheels stop by the base's own deadman
    (``dynamics``' ``cmd_vel_timeout``), the tick goes on without it after ``motion_limit``;
    the restarted executor takes the next ticks' goals.

    What the restarted executor did is read from its ``/diagnostics`` counters (motion
    primitives carried out), not from a status that happened to be sent mid-goal: those
    come once a second, and a goal of a second or less fell between two of them (a CI run
    heard none in the four ticks after the restart). The restarted process takes 2-5 ticks
    to start on a loaded machine (and aborts a goal that comes before the supervisor's
    first heartbeat), so the trial runs 11 ticks past the restart."""
    steps = 16
    with continuous_fault_trial(tmp_path, domain, 2, steps) as trial:
        killed = trial.wait_tick(3)
        assert trial.kill("executor_1") == -9
        restarted = trial.wait_tick(killed + 1)
        trial.restart("executor_1")
        result = trial.result()
        dynamics = trial.log("dynamics")
        world = json.loads((tmp_path / "world.json").read_text())
        driving = [
            int(m.group(1))
            for m in (re.fullmatch(r"driving tick (\d+)", t) for t in trial.messages(executor(1)))
            if m
        ]
        # statuses heard after the restart tick are the restarted process's
        done = [
            int(st.values["primitives"]) - int(st.values["primitives_aborted"])
            for st in trial.statuses(executor(1), since_tick=restarted + 1)
            if "primitives" in st.values
        ]
    print(
        f"executor_1 SIGKILLed at tick {killed}, restarted at tick {restarted}: late "
        f"{result['robots_late']}, missed {result['missed']}; robot 1 seen driving at ticks "
        f"{driving}; the restarted executor's primitives done {max(done, default=0)}; "
        f"dynamics took {world['late_steps']} steps without every cmd_vel"
    )
    assert len(result["tick_wall"]) == steps  # the trial ran to its end
    assert result["robots_late"] >= 1  # the dead executor's tick went on without it
    assert re.search(r"robot 1: no cmd_vel for [0-9.]+ s: wheels stopped", dynamics)
    # The simulator waited out one command_timeout for the dead executor, not one per step
    # until its wheels stopped (cmd_vel_timeout / dt = 10 steps: 50 s of a stalled team).
    assert world["late_steps"] <= 2
    assert max(done, default=0) >= 1  # the restarted executor drove or turned again
    words = np.array(result["commands"])
    assert words[restarted + 1 :, 1].any()  # robot 1's controller kept deciding


def test_team_tick_killed_and_restarted(tmp_path, domain):
    """The team tick's process is SIGKILLed: no snapshot, no goals, every executor finishes
    its primitive and stands; the restarted team tick begins again at tick 0 on the site as
    it is (a new trial of its own, which runs to its end)."""
    steps, robots = 6, 2
    with continuous_fault_trial(tmp_path, domain, robots, steps) as trial:
        killed = trial.wait_tick(3)
        assert trial.kill("team_tick") == -9
        dead = time.monotonic()
        trial.wait_seconds(15.0)  # every primitive ends within a few seconds
        heard = [
            s for k in range(robots) for s in trial.statuses(executor(k)) if s.wall > dead + 10.0
        ]
        trial.restart("team_tick")
        result = trial.result()
    print(
        f"team tick SIGKILLed at tick {killed}; executors heard 10-15 s later: "
        f"{sorted({(s.name, s.message) for s in heard})}; the restarted one ran "
        f"{len(result['tick_wall'])} ticks, missed {result['missed']}"
    )
    assert {s.name for s in heard} == {executor(k) for k in range(robots)}
    assert all(s.message == "ready" for s in heard)  # no robot driving without a team tick
    assert len(result["tick_wall"]) == steps  # the restarted tick ran a whole trial
    assert any(any(w) for w in result["commands"])  # and the robots acted in it
