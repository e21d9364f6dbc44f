"""Site files (ant-site/1): every inconsistency named; node parameters generated from one file."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import pytest
import yaml

from excavation_bringup import site as sitefile
from excavation_bringup.dome import dome_graph, main, site_problems
from excavation_common.params import validate

SITES = Path(__file__).parent / "data" / "sites"
CONFIG = Path(__file__).resolve().parents[1] / "ros2_ws/src/excavation_bringup/config"

BROKEN = {
    "grid_mismatch": "worksite.rows/cols = [20, 16]: the blueprint is 16 x 16 cells",
    "soil_unit": "worksite.soil_unit = 0.1: the blueprint's height_unit is 0.05 m",
    "cell_size": "worksite.cell_size = 0.5: the blueprint's is 0.25 m",
    "duplicate_leds": "robots[1].leds = ['red', 'green']: the same pair as robots[0]",
    "map_info": "overrides.mapper.publish_map_info = True: more than one map_info publisher",
    "no_calibration": "camera.calibration = '': required",
    "missing_calibration": "nowhere.yaml': does not exist",
    "robot_name": "robots[1].name = 'robot_7': robots are named by their index: expected robot_1",
    "unknown_backend": "robots[1].blade.backend = 'can': must be one of sim, serial",
    "missing_genome": "nowhere.json': does not exist",
    "bad_genome": "bad_genome.json': cannot be loaded",
    "bad_domain": "network.domain = 300: must be in 0 .. 232",
    "discovery_range": "network.discovery_range = 'EVERYWHERE': must be one of LOCALHOST",
    "unknown_colour": "robots[1].leds = ['blue', 'purple']: 'purple' is not in",
    "sim_blade": "robots[1].blade.backend = 'sim': only with --sim (the simulator is that "
    "blade's board)",
    "serial_no_port": "robots[1].blade.port = '': the serial backend needs the board's port",
    "same_port": "robots[1].blade.port = '/dev/ttyUSB0': robots[0] uses it too",
    "compressed_topic": "camera.image_topic = '/overhead/image_raw': jpeg frames are a Compressed",
    "bad_format": "format = 'ant-site/2': expected 'ant-site/1'",
    "unknown_key": "camera.fps = 30: unknown key",
    "laser_outside": "laser.mount = [9.0, 2.0, 4.0]: is outside the 4.0 x 4.0 m worksite",
    "derived_override": "overrides.controller.height_unit = 0.1: the graph sets it from the "
    "site file or the run's options (excavation_bringup.nodes.controller)",
    "duplicate_key": "network = 'line 17 column 1': is given twice (first at line 16 column 1)",
    "same_drive_topic": "robots[1].drive_topic = '/base_1/cmd_vel': robots[0] drives "
    "/base_1/cmd_vel too",
    "drive_type": "robots[1].drive_type = 'twist_mux': must be one of twist_stamped, twist",
    "imu_flag": "robots[1].imu = 'yes': expected true or false",
    "tilt_override": "overrides.controller.tilt_source = 'imu': the graph sets it from the "
    "site file or the run's options (excavation_bringup.nodes.controller)",
    "override_type": "overrides.executor.max_speed = 'fast': expected a number",
    "override_range": "overrides.team_tick.blade_wait = -1.0: must be >= 0.0",
    "override_choice": "overrides.executor.mode = 'auto': must be one of tick, free",
    "override_rule": "overrides.executor = {'max_speed': 0.2}: throttle_speed 0.15 < max_speed 0.2",
    "sim_soil": "sim.soil = 'sand': soil = 'sand': 'sand' is not one of grid, physical",
}


def test_the_good_site_and_the_shipped_sites_are_consistent():
    assert sitefile.check_site(SITES / "good.yaml")[1] == []
    assert sitefile.check_site(CONFIG / "site_sim.yaml", sim=True)[1] == []


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_each_broken_site_gives_its_message(name, capsys):
    """The site's own checks, then the graph's: a refused override names its field."""
    path = SITES / f"{name}.yaml"
    messages = site_problems(path)
    assert len(messages) == 1, messages  # each file breaks one thing
    assert messages[0].startswith(str(path) + ": ")
    assert BROKEN[name] in messages[0]
    assert main(["check", str(path)]) == 1
    assert BROKEN[name] in capsys.readouterr().out


def test_every_broken_file_is_tested():
    shipped = {p.stem for p in SITES.glob("*.yaml")} - {"good"}
    assert shipped == set(BROKEN)


def test_sim_checks_what_the_simulator_renders(tmp_path):
    text = (
        (CONFIG / "site_sim.yaml").read_text().replace("leds: [blue, yellow]", "leds: [cyan, red]")
    )
    text = text.replace("mount: [2.0, 2.0, 4.0]", "mount: [2.0, 2.0, 5.0]")
    text = text.replace("../../../../genomes", str(Path(__file__).resolve().parents[1] / "genomes"))
    (tmp_path / "s.yaml").write_text(text)
    _, errors = sitefile.check_site(tmp_path / "s.yaml", sim=True)
    messages = "\n".join(map(str, errors))
    assert (
        "robots[1].leds = ['cyan', 'red']: the simulator's robot 1 carries ['blue', 'yellow']"
        in messages
    )
    assert "laser.mount = [2.0, 2.0, 5.0]: the simulator's laser is at [2.0, 2.0, 4.0]" in messages
    _, errors = sitefile.check_site(CONFIG / "site_sim.yaml")  # not for the real dome
    assert [e.field for e in errors] == [
        "camera.calibration",
        "robots[0].blade.backend",
        "robots[1].blade.backend",
    ]


def test_the_dome_template_lacks_only_its_calibration_and_drives_every_base(tmp_path, capsys):
    """``ant-dome check site_dome.yaml``: the template's one gap is the camera file it names."""
    from team_tick.core import TeamTickParams
    from team_tick.node import TeamTickNodeParams

    from drive_executor.params import ExecutorParams

    template = CONFIG / "site_dome.yaml"
    site, errors = sitefile.check_site(template)
    assert [e.field for e in errors] == ["camera.calibration"]
    assert "does not exist (run `calibrate`" in str(errors[0])
    assert main(["check", str(template)]) == 1
    assert capsys.readouterr().out.count("camera.calibration") == 1
    table = dome_graph(site, tmp_path).nodes
    by_name = {s.name: s for s in table}
    assert table[0].name == "supervisor" and table[0].params["arm_at_start"] is False
    assert not any(s.sim_time for s in table)  # the dome runs on wall time
    for k, robot in enumerate(site.robots):
        executor = by_name[f"executor_{k}"]
        assert executor.kind == "executor"
        assert executor.remaps == (f"/robot_{k}/cmd_vel:={robot.drive_topic}",)
        validate(ExecutorParams, executor.params, executor.name)
    tick = by_name["team_tick"]
    own = {f.name for f in fields(TeamTickParams)}
    validate(TeamTickParams, {k: v for k, v in tick.params.items() if k in own}, "team_tick")
    validate(TeamTickNodeParams, {k: v for k, v in tick.params.items() if k not in own})
    assert tick.params["robots"] == site.n_robots == 2


def test_missing_file_and_load_site_raises(tmp_path):
    _, errors = sitefile.check_site(tmp_path / "nope.yaml")
    assert "does not exist" in str(errors[0])
    with pytest.raises(sitefile.SiteError, match="worksite.soil_unit"):
        sitefile.load_site(SITES / "soil_unit.yaml")


def _config_keys(kind: str) -> set[str]:
    """Every parameter node kind ``kind`` declares (the registry's dataclasses)."""
    return sitefile.node_parameter_names(kind)


@pytest.mark.parametrize("sim", [False, True])
def test_generated_parameters_are_parameters_of_each_node(tmp_path, sim):
    from overhead_localizer.localize import LocalizerParams
    from overhead_localizer.params import LocalizerNodeParams
    from terrain_mapper.mapper import MapperParams
    from terrain_mapper.params import MapperNodeParams

    path = CONFIG / "site_sim.yaml" if sim else SITES / "good.yaml"
    site = sitefile.load_site(path, sim=sim)
    hardware = "sim" if sim else "dome"
    table = dome_graph(site, tmp_path, hardware, record=str(tmp_path / "bag"), view=True).nodes
    names = [s.name for s in table]
    # the recorder first (it sees every topic); with --sim the simulated robots and the
    # clock (dynamics, the executors), then the team supervisor; in the dome the executors
    # follow the blade drivers (the supervisor, disarmed, is up before anything can move)
    robots = ["blade_driver_0", "blade_driver_1", "executor_0", "executor_1"]
    if sim:
        head = ["recorder", "dynamics", "executor_0", "executor_1", "supervisor", "server"]
        head += ["sensors", "localizer", "mapper", "blade_driver_0", "blade_driver_1"]
    else:
        head = ["recorder", "supervisor", "server", "localizer", "mapper", *robots]
    tail = ["controller_0", "controller_1", "team_tick", "view"]
    assert names == head + tail
    by_name = {s.name: s for s in table}
    for spec in table:
        # every node but the clock, the recorder and the view runs on the simulator's clock
        assert "use_sim_time" not in spec.params  # a ROS parameter, not the node's own
        assert spec.ros_params().get("use_sim_time", False) is spec.sim_time
        assert spec.sim_time == (sim and spec.name not in ("dynamics", "recorder", "view"))
        if spec.kind in ("localizer", "mapper"):
            classes = (
                (LocalizerNodeParams, LocalizerParams)
                if spec.name == "localizer"
                else (MapperNodeParams, MapperParams)
            )
            for cls in classes:
                own = {f.name for f in fields(cls)}
                validate(cls, {k: v for k, v in spec.params.items() if k in own}, spec.name)
            assert set(spec.params) <= {f.name for c in classes for f in fields(c)}
    controller_keys = _config_keys("controller")
    executor_keys = _config_keys("executor")
    driver_keys = _config_keys("blade_driver")
    for k in range(site.n_robots):
        c = by_name[f"controller_{k}"]
        assert set(c.params) <= controller_keys and c.namespace == f"/robot_{k}"
        assert c.params["height_unit"] == site.worksite.soil_unit and c.params["robot_id"] == k
        assert c.params["lockstep"] is True  # once per team tick, in the dome too
        assert c.params["tilt_source"] == "imu"  # R1 from the robot's (or simulator's) IMU
        # the controller reads the team tick's snapshot, as in the --sim table
        ns = f"/robot_{k}"
        for j in range(site.n_robots):
            assert f"/robot_{j}/pose:=/tick/robot_{j}/pose" in c.remaps
        assert "/worksite/height_map:=/tick/worksite/height_map" in c.remaps
        assert f"{ns}/stuck:=/tick{ns}/stuck" in c.remaps
        # in the dome its blade state is the tick's too (the board's is on the wall clock)
        blade_remap = f"{ns}/blade/joint_states:={ns}/blade/tick_state"
        assert (blade_remap in c.remaps) == (not sim)
        driver = by_name[f"blade_driver_{k}"].params
        assert set(driver) <= driver_keys
        assert driver["blade_after_motion"] is True  # a tick's blade bits after its drive
        executor = by_name[f"executor_{k}"]
        assert set(executor.params) <= executor_keys and executor.namespace == ns
        assert executor.params["cell_size"] == site.worksite.cell_size
        if sim:
            assert executor.params["pose_topic"] == f"/truth{ns}/pose" and not executor.remaps
        else:
            # the localiser's pose, the team's 0.5 s wall-clock deadman, cmd_vel to the base
            assert executor.params["pose_topic"] == "pose"
            assert "deadman" not in executor.params
            assert executor.remaps == (f"{ns}/cmd_vel:={site.robots[k].drive_topic}",)
    tick = by_name["team_tick"]
    assert set(tick.params) <= _config_keys("team_tick")
    assert tick.params["robots"] == site.n_robots and not tick.restart
    assert tick.params.get("blade_in", "blade/plant_state") == (
        "blade/plant_state" if sim else "blade/joint_states"
    )
    assert tick.params.get("blade_out", "blade/servo_state") == (
        "blade/servo_state" if sim else "blade/tick_state"
    )
    assert set(by_name["server"].params) <= _config_keys("server")
    recorder = by_name["recorder"].params
    assert set(recorder) <= _config_keys("recorder")
    for topic in (site.camera.image_topic, site.laser.scan_topic, site.laser.mount_state_topic):
        assert topic in recorder["topics"]  # the site's own names are recorded too
    assert all(robot.drive_topic in recorder["topics"] for robot in site.robots)
    supervisor = by_name["supervisor"].params
    assert set(supervisor) <= _config_keys("supervisor")
    assert supervisor["robots"] == site.n_robots
    assert supervisor["arm_at_start"] is sim  # the dome starts disarmed: the operator arms
    # the one map_info publisher is the blueprint server
    assert by_name["mapper"].params["publish_map_info"] is False
    beacons = yaml.safe_load((tmp_path / "beacons.yaml").read_text())
    assert [(r["front"], r["rear"]) for r in beacons["robots"]] == [r.leds for r in site.robots]
    if not sim:
        assert by_name["blade_driver_1"].params == {
            "backend": "serial",
            "port": "/dev/ttyUSB1",
            "blade_after_motion": True,
        }
        assert by_name["localizer"].params["compressed"] is True
        assert by_name["mapper"].params["tilt_offset"] == 0.01
        assert by_name["controller_1"].args == ("--hand-coded",)
        # good.yaml: robot_1's base listens on its own topic
        assert by_name["executor_1"].remaps == ("/robot_1/cmd_vel:=/base_1/cmd_vel",)
        # the dome's team tick runs until stopped (Ctrl-C), its run does not end by itself
        assert tick.params["steps"] == 0 and not tick.final
    else:
        assert (tmp_path / "camera.yaml").exists()
        assert by_name["localizer"].params["calibration"] == str(tmp_path / "camera.yaml")
        assert set(by_name["dynamics"].params) <= _config_keys("dynamics")
        assert by_name["dynamics"].params["slip"] == 0.0  # site_sim.yaml: sim.exact
        assert tick.final and tick.params["steps"] == site.sim.ticks


def test_each_robot_names_its_base_type_and_imu_and_a_dome_tunes_executor_and_team_tick(
    tmp_path,
):
    """``drive_type`` and ``imu`` per robot reach their nodes; executor and team tick overrides
    are typed and win over the node spec functions' values; the dome's executors stop within
    the localiser's error (docs/benchmarks.md: p50 0.046 cell, 11.5 mm)."""
    from drive_executor.params import ExecutorParams

    text = (SITES / "good.yaml").read_text()
    text = text.replace("genome: hand-coded}", "genome: hand-coded, drive_type: twist, imu: false}")
    text = text.replace("../../../", str(Path(__file__).resolve().parents[1]) + "/")
    text += (
        "overrides:\n"
        "  executor: {time_allowance: 20, progress_window: 2.0}\n"
        "  team_tick: {blade_wait: 5.0, motion_limit: 60}\n"
    )
    (tmp_path / "site.yaml").write_text(text)
    site, errors = sitefile.check_site(tmp_path / "site.yaml")
    assert errors == [] and site_problems(tmp_path / "site.yaml") == []
    assert [(r.drive_type, r.imu) for r in site.robots] == [
        ("twist_stamped", True),
        ("twist", False),
    ]
    by_name = {s.name: s for s in dome_graph(site, tmp_path / "run").nodes}
    # an integer given for a double is the double rclpy needs (a params file keeps 20 an int)
    assert type(by_name["executor_0"].params["time_allowance"]) is float
    assert type(by_name["executor_0"].ros_params()["time_allowance"]) is float
    for k, (drive_type, tilt) in enumerate([("twist_stamped", "imu"), ("twist", "height_map")]):
        executor = by_name[f"executor_{k}"].params
        assert executor["drive_type"] == drive_type
        assert executor.get("cmd_vel_stamp", "now") == "now"  # the base times it from sending
        assert executor["time_allowance"] == 20.0 and executor["progress_window"] == 2.0
        assert executor["position_tolerance"] >= 0.0115 and executor["min_progress"] >= 0.0115
        assert executor["pose_timeout"] == 0.6  # the dome profile's: a localiser's pose
        validate(ExecutorParams, executor, f"executor_{k}")
        assert by_name[f"controller_{k}"].params["tilt_source"] == tilt
    tick = by_name["team_tick"].params
    assert tick["blade_wait"] == 5.0 and tick["motion_limit"] == 60.0
    # the simulated dome keeps the simulator's lockstep and the defaults every trial ran with
    sim = {s.name: s for s in dome_graph(site, tmp_path / "sim", "sim").nodes}
    executor = sim["executor_1"].params
    assert executor["cmd_vel_stamp"] == "pose" and "drive_type" not in executor
    assert "position_tolerance" not in executor and "min_progress" not in executor
    assert "pose_timeout" not in executor


def test_a_rehearsal_is_the_dome_table_behind_emulated_drivers(tmp_path):
    """``ant-dome rehearse``: the emulators first, then the dome's table, unchanged but for
    each blade driver's port (the emulated board's link); every parameter is its node's."""
    from excavation_bringup.kinds import kind

    site = sitefile.load_site(CONFIG / "site_rehearsal.yaml", emulated=True)
    dome_dir, rehearsal_dir = tmp_path / "dome", tmp_path / "rehearsal"
    dome = dome_graph(site, dome_dir, "dome", ticks=5).nodes
    rehearsal = dome_graph(site, rehearsal_dir, "emulated", ticks=5).nodes
    emulators = ["world", "base_0", "servo_board_0", "base_1", "servo_board_1", "camera", "laser"]
    assert [s.name for s in rehearsal] == emulators + [s.name for s in dome]
    same = {s.name: s for s in dome}

    def here(value):  # the rehearsal's run directory read as the dome's
        return value.replace(str(rehearsal_dir), str(dome_dir)) if isinstance(value, str) else value

    for spec in rehearsal[len(emulators) :]:
        other = same[spec.name]
        params = {k: here(v) for k, v in spec.params.items()}
        expected = dict(other.params)
        if spec.kind == "blade_driver":
            link = str(dome_dir / f"robot_{spec.name[-1]}_blade")
            assert params.pop("port") == link and expected.pop("port").startswith("/dev/tty")
        assert params == expected, spec.name
        assert (spec.remaps, spec.namespace, spec.args) == (
            other.remaps,
            other.namespace,
            other.args,
        )
    for spec in rehearsal:
        assert not spec.sim_time  # every node of a rehearsal on the wall clock
        for cls in kind(spec.kind).param_classes():
            own = {f.name for f in fields(cls)}
            validate(cls, {k: v for k, v in spec.params.items() if k in own}, spec.name)
    by_name = {s.name: s for s in rehearsal}
    world = by_name["world"]
    assert world.params["time_factor"] == 1.0 and world.params["blade_after_motion"] is False
    assert "/clock:=/sim/clock" in world.remaps
    assert by_name["base_1"].params == {"drive_type": "twist", "publish_imu": False}
    assert "/robot_1/cmd_vel:=/robot_1/cmd_vel_unstamped" in by_name["base_1"].remaps
    assert by_name["servo_board_0"].params["link"] == str(rehearsal_dir / "robot_0_blade")


def test_a_rehearsal_site_is_checked_for_the_emulators(tmp_path):
    text = (CONFIG / "site_rehearsal.yaml").read_text()
    assert sitefile.check_site(CONFIG / "site_rehearsal.yaml", emulated=True)[1] == []
    # the dome itself refuses the simulated calibration
    assert any(
        e.field == "camera.calibration"
        for e in sitefile.check_site(CONFIG / "site_rehearsal.yaml")[1]
    )
    bad = tmp_path / "s.yaml"
    genome = str((CONFIG / "../../../../genomes/best.json").resolve())
    text = text.replace("../../../../genomes/best.json", genome)
    bad.write_text(text.replace("encoding: jpeg", "encoding: png"))
    _, errors = sitefile.check_site(bad, emulated=True)
    assert [(e.field, e.value) for e in errors] == [("camera.encoding", "png")]


def test_repeated_keys_are_refused_anywhere():
    with pytest.raises(sitefile.SiteError, match=r"a = 'line 3 column 3': is given twice"):
        sitefile.safe_load_unique("x:\n  a: 1\n  a: 2\n", "t.yaml")
    assert sitefile.safe_load_unique("x: {a: 1, b: 2}", "t.yaml") == {"x": {"a": 1, "b": 2}}


VARIANTS = [
    ("seed: 0", "seed: 3"),
    ("scenario: 0", "scenario: 2"),
    ("ticks: 20", "ticks: 7"),
    ("command_timeout: 60.0", "command_timeout: 50.0"),
    ("sweep_scans: 32", "sweep_scans: 48"),
    ("mount: [2.0, 2.0, 4.0]", "mount: [2.0, 2.1, 3.9]"),
    ("imu: true", "imu: false"),
    ("drive_type: twist\n", "drive_type: twist_stamped\n"),
    ("drive_topic: /robot_1/cmd_vel_unstamped", "drive_topic: /robot_1/base/cmd_vel"),
    ("leds: [blue, yellow]", "leds: [blue, yellow]\n    genome: hand-coded"),
]


@pytest.mark.parametrize(("old", "new"), VARIANTS, ids=[v[1].split(":")[0] for v in VARIANTS])
def test_every_parameter_the_site_changes_is_declared_derived(tmp_path, old, new):
    """A parameter that follows a site field is derived (an override of it is refused).

    Each variant changes one field of the shipped rehearsal site; every node parameter that
    changes with it must be one its node spec function gives as derived.
    """
    text = (CONFIG / "site_rehearsal.yaml").read_text()
    assert old in text
    genomes = str(CONFIG.parents[3] / "genomes") + "/"
    variant = text.replace(old, new).replace("../../../../genomes/", genomes)
    if "genome: hand-coded" in variant:  # the variant's robot_1: drop its file genome
        head, tail = variant.split("genome: hand-coded", 1)
        variant = head + "genome: hand-coded" + tail.replace(f"genome: {genomes}best.json", "", 1)
    base = tmp_path / "base.yaml"
    base.write_text(text.replace("../../../../genomes/", genomes))
    changed = tmp_path / "changed.yaml"
    changed.write_text(variant)
    run = tmp_path / "run"
    graphs = [
        dome_graph(sitefile.load_site(p, emulated=True), run, "emulated") for p in (base, changed)
    ]
    moved, elsewhere = set(), False  # a topic or a genome moves remaps or arguments
    undeclared = set()
    for a, b in zip(graphs[0].nodes, graphs[1].nodes, strict=True):
        assert a.name == b.name
        elsewhere |= (a.remaps, a.args) != (b.remaps, b.args)
        changed = {
            k for k in a.params.keys() | b.params.keys() if a.params.get(k) != b.params.get(k)
        }
        moved |= {(a.kind, k) for k in changed}
        undeclared |= {(a.kind, k) for k in changed if k not in b.params.derived}
    assert moved or elsewhere, f"{new!r} changed nothing in the graph"
    assert not undeclared, f"{new!r} sets {sorted(undeclared)}: give them as derived"


def test_sim_soil_reaches_the_simulated_worlds_dynamics(tmp_path):
    """``sim.soil: physical`` in a site file runs ``ant-dome up --sim`` on physical soil;
    the synthetic laser then sees the fine field."""
    text = (CONFIG / "site_sim.yaml").read_text().replace("soil: grid ", "soil: physical ")
    text = text.replace("../../../../genomes", str(Path(__file__).resolve().parents[1] / "genomes"))
    (tmp_path / "s.yaml").write_text(text)
    site, errors = sitefile.check_site(tmp_path / "s.yaml", sim=True)
    assert errors == [] and site.sim.soil == "physical"
    nodes = {s.name: s for s in dome_graph(site, tmp_path / "run", "sim").nodes}
    assert nodes["dynamics"].params["soil"] == "physical"
    assert nodes["dynamics"].params["fine_height_map"] is True
    lunar = tmp_path / "lunar.yaml"
    lunar.write_text(text.replace("soil: physical ", "soil: 'physical:lunar,repose=false' "))
    site, errors = sitefile.check_site(lunar, sim=True)
    assert errors == [] and site.sim.soil == "physical:lunar,repose=false"
    nodes = {s.name: s for s in dome_graph(site, tmp_path / "run2", "sim").nodes}
    assert nodes["dynamics"].params["soil"] == "physical:lunar,repose=false"
    assert nodes["dynamics"].params["fine_height_map"] is True
    grid = sitefile.check_site(CONFIG / "site_sim.yaml", sim=True)[0]
    assert {s.name: s for s in dome_graph(grid, tmp_path / "g", "sim").nodes}["dynamics"].params[
        "soil"
    ] == "grid"


def test_a_robot_field_sets_its_own_node_parameter_declared_once(tmp_path):
    """``robots[k].max_speed`` (a ``node_param`` field): read and checked as the executor's
    ``max_speed`` is declared, given to robot k's executor as derived (an override cannot
    contradict it), other robots keep the graph's value; a rule across the executor's
    parameters is judged on the graph."""
    from excavation_bringup.generate import site_block

    text = (CONFIG / "site_rehearsal.yaml").read_text()
    genomes = str(CONFIG.parents[3] / "genomes") + "/"
    text = text.replace("../../../../genomes/", genomes)
    assert "  - name: robot_1\n" in text

    def variant(value: str, extra: str = "") -> Path:
        path = tmp_path / f"{value}{len(extra)}.yaml"
        path.write_text(
            text.replace("  - name: robot_1\n", f"  - name: robot_1\n    max_speed: {value}\n")
            + extra
        )
        return path

    good = variant("0.05")
    assert site_problems(good, "emulated") == []
    site = sitefile.load_site(good, emulated=True)
    assert site.robots[1].max_speed == 0.05 and site.robots[0].max_speed is None
    nodes = {s.name: s for s in dome_graph(site, tmp_path / "run", "emulated").nodes}
    assert nodes["executor_1"].params["max_speed"] == 0.05
    assert "max_speed" in nodes["executor_1"].params.derived
    assert "max_speed" not in nodes["executor_0"].params  # the node's own default
    # an override of it is refused for the robot that sets it only
    lines = site_problems(
        variant("0.05", "overrides:\n  executor: {max_speed: 0.08}\n"), "emulated"
    )
    assert len(lines) == 1 and "overrides.executor.max_speed = 0.08: the graph sets it" in lines[0]
    # checked as the parameter is declared, naming the site's field
    lines = site_problems(variant("fast"), "emulated")
    assert len(lines) == 1 and "robots[1].max_speed = 'fast': expected a number" in lines[0]
    lines = site_problems(variant("9.0"), "emulated")
    assert len(lines) == 1 and "robots[1].max_speed = 9.0: must be <= 5.0" in lines[0]
    lines = site_problems(variant("0.2"), "emulated")  # above throttle_speed 0.15
    assert lines == [
        f"{tmp_path / '0.20.yaml'}: node executor_1 would refuse its parameters: "
        "throttle_speed 0.15 < max_speed 0.2"
    ]
    assert "`robots[k].max_speed` | `executor` `max_speed`" in site_block()
