"""The site file (``format: ant-site/1``): one YAML file that describes a dome (paper, 6).

A site file names everything the node suite needs to run in one dome: the worksite
(blueprint, grid, cell size, soil unit), the overhead camera (image topic and encoding,
CameraInfo topic, calibration file, LED table), the overhead laser (scan and mount topics,
mount position and orientation offsets), the robots (name, LED pair, blade backend and port,
drive topic and the base's message type, whether it carries an IMU, controller genome, the
host that runs its drive executor and blade driver), the hosts (the dome PC first, then the
robots' computers: name and address) and the network (ROS domain, discovery range, static
peers). Every node's parameters are made from it by the
node spec functions of :mod:`excavation_bringup.nodes` (through a
:class:`~excavation_bringup.deployment.Deployment`), so a value such as the soil unit is
written once.

:func:`load_site` reads and checks a file; :func:`check_site` returns every problem it
finds (each a :class:`SiteError` naming file, field and value), which is what
``ant-dome check SITE`` prints. Paths in the file are relative to the file. An annotated
example is ``config/site_dome.yaml``; ``docs/dome.md`` is the walkthrough.

Pure module (PyYAML, numpy and the node packages' pure loaders), no ``rclpy``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from excavation_common.errors import FieldError
from excavation_common.loaders import parse_yaml, read_text_bounded
from excavation_common.network import (
    DISCOVERY_RANGES,
    MAX_DOMAIN,
    MAX_STATIC_PEERS,
    OFF_WITH_PEERS,
    Network,
    valid_address,
    yaml_range,
)
from excavation_common.topics import topic_name_problem
from excavation_sim.soil import SoilError, check_soil

FORMAT = "ant-site/1"

RAW_ENCODINGS = (
    "bgr8",
    "rgb8",
    "bgra8",
    "rgba8",
    "mono8",
    "bayer_rggb8",
    "bayer_bggr8",
    "bayer_gbrg8",
    "bayer_grbg8",
    "yuv422",
    "uyvy",
    "yuv422_yuy2",
    "yuyv",
)
"""``sensor_msgs/Image`` encodings the localizer decodes."""

COMPRESSED_FORMATS = ("jpeg", "png")
"""``sensor_msgs/CompressedImage`` formats the localizer decodes."""

BACKENDS = ("sim", "serial")
"""Blade driver backends (``blade_driver``'s ``backend`` parameter)."""

DRIVE_TYPES = ("twist_stamped", "twist")
"""``cmd_vel`` message types a base takes (the drive executor's ``drive_type``)."""


SIMULATED = "simulated"
"""``camera.calibration`` value for ``--sim``: the simulator's camera, calibrated at
bring-up from surveyed marks exactly as ``ant-trial --perception full`` does."""

HAND_CODED = "hand-coded"
"""``robots[k].genome`` value for the paper's hand-coded controller."""

MAP_INFO_OWNER = "server"
"""The one node that publishes ``/worksite/map_info`` in a site: the blueprint server."""


class SiteError(FieldError):
    """A site file that cannot be used: ``file: field = value: reason``."""


def safe_load_unique(text: str, path: str) -> Any:
    """YAML ``text`` parsed safely (``excavation_common.loaders.parse_yaml``).

    A repeated key, an alias or a syntax error is a :class:`SiteError`.
    """
    return parse_yaml(text, path, SiteError)


# --- the model --------------------------------------------------------------------------------


def node_param(kind: str, name: str) -> Any:
    """A site field that sets parameter ``name`` of node kind ``kind`` (default: unset).

    Declared once: the reader reads and checks it as that parameter is declared (its type,
    range and choices, :mod:`excavation_common.params`), the node spec functions give it to
    the node as derived (:func:`node_values`, so an ``overrides:`` entry cannot contradict
    it), and ``make params`` lists it in docs/dome.md. Unset (``None``), the node keeps the
    graph's value. A field of :class:`Robot` goes to that robot's node.
    """
    return field(default=None, metadata={"node_param": (kind, name)})


def node_fields(cls: type) -> list[tuple[str, str, str]]:
    """``(field, kind, parameter)`` of each :func:`node_param` field of dataclass ``cls``."""
    from dataclasses import fields

    return [(f.name, *f.metadata["node_param"]) for f in fields(cls) if "node_param" in f.metadata]


@dataclass(frozen=True)
class Worksite:
    """The grid the robots dig: blueprint spec (or absolute file), its size and units."""

    blueprint: str = "default"
    rows: int = 16
    cols: int = 16
    cell_size: float = 0.25
    soil_unit: float = 0.05
    prior_height: float | None = 0.0


@dataclass(frozen=True)
class Camera:
    """The overhead camera's topics and calibration (files absolute, or ``SIMULATED``)."""

    image_topic: str = "/overhead/image_raw"
    encoding: str = "bgr8"
    camera_info_topic: str = ""
    calibration: str = ""
    beacons: str = ""

    @property
    def compressed(self) -> bool:
        """True when frames arrive as ``sensor_msgs/CompressedImage``."""
        return self.encoding in COMPRESSED_FORMATS


@dataclass(frozen=True)
class Laser:
    """The overhead laser: topics, pan/tilt centre in ``map`` and orientation offsets."""

    scan_topic: str = "/worksite/scan"
    mount_state_topic: str = "/worksite/laser_mount/joint_states"
    mount: tuple[float, float, float] = (2.0, 2.0, 4.0)
    pan_offset: float = 0.0
    tilt_offset: float = 0.0
    roll_offset: float = 0.0
    sweep_scans: int = 64
    robot_height: float = 0.2


@dataclass(frozen=True)
class Robot:
    """One robot: ``robot_k``, its LED pair, blade backend and port, drive topic, genome.

    ``drive_type``: the message its base takes on ``drive_topic`` (:data:`DRIVE_TYPES`);
    ``imu``: it carries an IMU on ``/robot_k/imu`` (its controller's R1 source). The fields
    after ``host`` each set one parameter of the robot's own node (:func:`node_param`).
    """

    name: str
    leds: tuple[str, str]
    backend: str = "sim"
    port: str = ""
    drive_topic: str = ""
    genome: str = HAND_CODED
    drive_type: str = "twist_stamped"
    imu: bool = True
    host: str = ""
    max_speed: float | None = node_param("executor", "max_speed")
    max_turn_rate: float | None = node_param("executor", "max_turn_rate")

    @property
    def drive_topic_resolved(self) -> str:
        """``drive_topic`` as a full name (a relative one is in the robot's namespace)."""
        topic = self.drive_topic
        return topic if topic.startswith("/") else f"/{self.name}/{topic}"


LOCAL = "local"
"""A host's ``address`` for the machine ``ant-dome`` runs on."""

MAX_HOSTS = 64
"""Most hosts a site may name."""

_HOST_NAME = re.compile(r"^[a-z][a-z0-9_-]{0,31}$")


@dataclass(frozen=True)
class Host:
    """A computer of the dome: ``name`` (``ant-dome up --host NAME``) and its address.

    ``address``: an IP address or host name its peers reach it at, or ``local``.
    """

    name: str
    address: str = LOCAL


DOME_PC = Host("dome", LOCAL)
"""The hosts of a site without a ``hosts`` section: one dome PC, this machine."""


@dataclass(frozen=True)
class SimSettings:
    """What ``ant-dome up --sim`` simulates: scenario seed and index, ticks, tick timeouts.

    ``first_command_timeout`` is tick 0's: every node's first frame, sweep and decision
    (numba kernels compiling) can take a loaded machine well over a minute. ``exact``:
    no slip and no noise in the continuous-motion simulator (``ant-trial --no-slip``), the
    setting whose result does not depend on the machine's timing. ``soil``: the simulated
    world's soil, ``grid`` (the world model's rules) or ``physical`` (``ant-trial --soil``).
    """

    seed: int = 0
    scenario: int = 0
    ticks: int = 300
    command_timeout: float = 30.0
    first_command_timeout: float = 180.0
    exact: bool = False
    soil: str = "grid"


@dataclass(frozen=True)
class Site:
    """A parsed site file (see the module docstring)."""

    path: str
    worksite: Worksite
    camera: Camera
    laser: Laser
    robots: tuple[Robot, ...]
    network: Network
    sim: SimSettings = field(default_factory=SimSettings)
    overrides: dict[str, dict[str, Any]] = field(default_factory=dict)
    hosts: tuple[Host, ...] = (DOME_PC,)

    @property
    def n_robots(self) -> int:
        """Team size."""
        return len(self.robots)

    @property
    def dome_host(self) -> str:
        """The dome PC's name: the first host (the supervisor, perception, the team tick)."""
        return self.hosts[0].name

    def robot_host(self, k: int) -> str:
        """The host that runs robot ``k``'s drive executor and blade driver."""
        return self.robots[k].host or self.dome_host


# --- reading ----------------------------------------------------------------------------------


class _Reader:
    """Reads typed fields out of the YAML tree, collecting errors instead of stopping."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.errors: list[SiteError] = []
        self.base = Path(path).resolve().parent

    def error(self, where: str, value: object, reason: str) -> None:
        self.errors.append(SiteError(self.path, where, value, reason))

    def section(self, doc: dict, key: str, allowed: set[str], required: bool = True) -> dict:
        value = doc.get(key)
        if value is None:
            if required:
                self.error(key, None, "missing section")
            return {}
        if not isinstance(value, dict):
            self.error(key, value, "expected a mapping")
            return {}
        for extra in sorted(set(value) - allowed):
            self.error(f"{key}.{extra}", value[extra], f"unknown key (known: {sorted(allowed)})")
        return value

    def number(self, sec, where, key, default, low=None, high=None, integer=False, positive=False):
        value = sec.get(key, default)
        kind = "an integer" if integer else "a number"
        ok = not isinstance(value, bool) and isinstance(value, int if integer else (int, float))
        if not ok or not math.isfinite(value):
            self.error(f"{where}.{key}", value, f"expected {kind}")
            return default
        if positive and value <= 0:
            self.error(f"{where}.{key}", value, "must be > 0")
            return default
        if (low is not None and value < low) or (high is not None and value > high):
            self.error(f"{where}.{key}", value, f"must be in {low} .. {high}")
            return default
        return int(value) if integer else float(value)

    def text(self, sec, where, key, default, choices=None, topic=False):
        value = sec.get(key, default)
        if not isinstance(value, str):
            self.error(f"{where}.{key}", value, "expected a string")
            return default
        if choices is not None and value not in choices:
            self.error(f"{where}.{key}", value, f"must be one of {', '.join(choices)}")
            return default
        problem = topic_name_problem(value) if topic and value else None
        if problem:
            self.error(f"{where}.{key}", value, f"is not a valid ROS topic name: {problem}")
            return default
        return value

    def file(self, value: str) -> str:
        """A path relative to the site file, made absolute."""
        return str((self.base / value).resolve())


def _worksite(r: _Reader, doc: dict) -> Worksite:
    keys = {"blueprint", "rows", "cols", "cell_size", "soil_unit", "prior_height"}
    s = r.section(doc, "worksite", keys)
    d = Worksite()
    bp = r.text(s, "worksite", "blueprint", d.blueprint)
    if bp not in ("default", "landing-pad") and not bp.startswith("default:"):
        bp = r.file(bp)
    return Worksite(
        bp,
        r.number(s, "worksite", "rows", d.rows, integer=True, positive=True),
        r.number(s, "worksite", "cols", d.cols, integer=True, positive=True),
        r.number(s, "worksite", "cell_size", d.cell_size, positive=True),
        r.number(s, "worksite", "soil_unit", d.soil_unit, positive=True),
        None
        if s.get("prior_height", 0.0) is None
        else r.number(s, "worksite", "prior_height", 0.0),
    )


def _camera(r: _Reader, doc: dict) -> Camera:
    keys = {"image_topic", "encoding", "camera_info_topic", "calibration", "beacons"}
    s = r.section(doc, "camera", keys)
    d = Camera()
    encoding = r.text(s, "camera", "encoding", d.encoding, RAW_ENCODINGS + COMPRESSED_FORMATS)
    calibration = r.text(s, "camera", "calibration", d.calibration)
    if calibration and calibration != SIMULATED:
        calibration = r.file(calibration)
    beacons = r.text(s, "camera", "beacons", d.beacons)
    return Camera(
        r.text(s, "camera", "image_topic", d.image_topic, topic=True),
        encoding,
        r.text(s, "camera", "camera_info_topic", d.camera_info_topic, topic=True),
        calibration,
        r.file(beacons) if beacons else "",
    )


def _laser(r: _Reader, doc: dict) -> Laser:
    keys = {"scan_topic", "mount_state_topic", "mount", "offsets", "sweep_scans", "robot_height"}
    s = r.section(doc, "laser", keys)
    d = Laser()
    mount = s.get("mount", list(d.mount))
    ok = isinstance(mount, list) and len(mount) == 3
    ok = ok and all(isinstance(v, int | float) and not isinstance(v, bool) for v in mount)
    if not ok or not all(math.isfinite(v) for v in mount):
        r.error("laser.mount", mount, "expected [x, y, z] in map, metres")
        mount = list(d.mount)
    elif mount[2] <= 0:
        r.error("laser.mount", mount, "z (height above the floor) must be > 0")
    off = s.get("offsets", {})
    if not isinstance(off, dict):
        r.error("laser.offsets", off, "expected a mapping {pan, tilt, roll} (radians)")
        off = {}
    for extra in sorted(set(off) - {"pan", "tilt", "roll"}):
        r.error(f"laser.offsets.{extra}", off[extra], "unknown key (known: pan, tilt, roll)")
    lim = 0.5
    return Laser(
        r.text(s, "laser", "scan_topic", d.scan_topic, topic=True),
        r.text(s, "laser", "mount_state_topic", d.mount_state_topic, topic=True),
        tuple(float(v) for v in mount),
        r.number(off, "laser.offsets", "pan", 0.0, -lim, lim),
        r.number(off, "laser.offsets", "tilt", 0.0, -lim, lim),
        r.number(off, "laser.offsets", "roll", 0.0, -lim, lim),
        r.number(s, "laser", "sweep_scans", d.sweep_scans, 2, 10000, integer=True),
        r.number(s, "laser", "robot_height", d.robot_height, positive=True),
    )


def _robots(r: _Reader, doc: dict) -> tuple[Robot, ...]:
    entries = doc.get("robots")
    if not isinstance(entries, list) or not entries:
        r.error("robots", entries, "expected a non-empty list of robots")
        return ()
    out = []
    keys = {"name", "leds", "blade", "drive_topic", "drive_type", "imu", "genome", "host"}
    keys |= {name for name, _, _ in node_fields(Robot)}
    for k, entry in enumerate(entries):
        where = f"robots[{k}]"
        if not isinstance(entry, dict):
            r.error(where, entry, "expected a mapping")
            continue
        for extra in sorted(set(entry) - keys):
            r.error(f"{where}.{extra}", entry[extra], f"unknown key (known: {sorted(keys)})")
        name = r.text(entry, where, "name", f"robot_{k}")
        if name != f"robot_{k}":
            r.error(f"{where}.name", name, f"robots are named by their index: expected robot_{k}")
        leds = entry.get("leds")
        pair = isinstance(leds, list) and len(leds) == 2
        if not (pair and all(isinstance(c, str) for c in leds)):
            r.error(f"{where}.leds", leds, "expected [front colour, rear colour]")
            leds = ["?", "?"]
        elif leds[0] == leds[1]:
            r.error(f"{where}.leds", leds, "front and rear need different colours")
        blade = entry.get("blade", {})
        if not isinstance(blade, dict):
            r.error(f"{where}.blade", blade, "expected a mapping {backend, port}")
            blade = {}
        for extra in sorted(set(blade) - {"backend", "port"}):
            r.error(f"{where}.blade.{extra}", blade[extra], "unknown key (known: backend, port)")
        backend = r.text(blade, f"{where}.blade", "backend", "sim", BACKENDS)
        if backend != blade.get("backend", "sim"):
            backend = ""  # refused above: no check of a backend applies
        port = r.text(blade, f"{where}.blade", "port", "")
        if backend == "serial" and not port:
            r.error(f"{where}.blade.port", port, "the serial backend needs the board's port")
        genome = r.text(entry, where, "genome", HAND_CODED)
        imu = entry.get("imu", True)
        if not isinstance(imu, bool):
            r.error(f"{where}.imu", imu, "expected true or false (does the robot carry an IMU?)")
            imu = True
        out.append(
            Robot(
                name,
                (leds[0], leds[1]),
                backend,
                port,
                r.text(entry, where, "drive_topic", f"/{name}/cmd_vel", topic=True),
                genome if genome == HAND_CODED else r.file(genome),
                r.text(entry, where, "drive_type", "twist_stamped", DRIVE_TYPES),
                imu,
                r.text(entry, where, "host", ""),
                **_node_values(r, entry, where, Robot),
            )
        )
    return tuple(out)


def _node_values(r: _Reader, entry: dict, where: str, cls: type) -> dict[str, Any]:
    """The :func:`node_param` fields of ``cls`` given in ``entry``, each checked.

    Each is checked as its node parameter is declared; a rule across the node's parameters
    is judged on the graph.
    """
    from excavation_bringup.kinds import kind as node_kind
    from excavation_common.params import ParameterError, specs, validate

    out = {}
    for name, kind, param in node_fields(cls):
        if name not in entry:
            continue
        target = next(c for c in node_kind(kind).param_classes() if param in specs(c))
        try:
            value = getattr(validate(target, {param: entry[name]}, kind), param)
        except ParameterError as exc:
            if exc.field == param:
                r.error(f"{where}.{name}", entry[name], exc.reason)
                continue
            value = entry[name]  # a rule across fields: the graph judges it
        out[name] = value
    return out


def node_values(site: Site, kind: str, k: int | None = None) -> dict[str, Any]:
    """What ``site``'s :func:`node_param` fields set of node kind ``kind``'s parameters.

    Robot ``k``'s fields for a per-robot node (``k`` given); only the fields given.
    """
    out = {}
    if k is not None:
        robot = site.robots[k]
        for name, node, param in node_fields(Robot):
            if node == kind and getattr(robot, name) is not None:
                out[param] = getattr(robot, name)
    return out


def _network(r: _Reader, doc: dict) -> Network:
    s = r.section(doc, "network", {"domain", "discovery_range", "static_peers"})
    d = Network()
    peers = s.get("static_peers", [])
    if not isinstance(peers, list) or len(peers) > MAX_STATIC_PEERS:
        r.error("network.static_peers", peers, f"expected a list of at most {MAX_STATIC_PEERS}")
        peers = []
    for i, peer in enumerate(peers):
        if not valid_address(peer):
            r.error(f"network.static_peers[{i}]", peer, "expected an IP address or a host name")
    if "discovery_range" in s:
        s = s | {"discovery_range": yaml_range(s["discovery_range"])}
    network = Network(
        r.number(s, "network", "domain", d.domain, 0, MAX_DOMAIN, integer=True),
        r.text(s, "network", "discovery_range", d.discovery_range, DISCOVERY_RANGES),
        tuple(p for p in peers if valid_address(p)),
    )
    if network.static_peers and network.discovery_range == "OFF":
        r.error("network.static_peers", list(network.static_peers), OFF_WITH_PEERS)
    return network


def _hosts(r: _Reader, doc: dict) -> tuple[Host, ...]:
    entries = doc.get("hosts")
    if entries is None:
        return (DOME_PC,)
    if not isinstance(entries, list) or not entries or len(entries) > MAX_HOSTS:
        r.error("hosts", entries, f"expected a list of 1 .. {MAX_HOSTS} hosts, the dome PC first")
        return (DOME_PC,)
    out: list[Host] = []
    addresses: dict[str, int] = {}
    for i, entry in enumerate(entries):
        where = f"hosts[{i}]"
        if not isinstance(entry, dict):
            r.error(where, entry, "expected a mapping {name, address}")
            continue
        for extra in sorted(set(entry) - {"name", "address"}):
            r.error(f"{where}.{extra}", entry[extra], "unknown key (known: address, name)")
        name = entry.get("name")
        if not isinstance(name, str) or not _HOST_NAME.match(name):
            r.error(f"{where}.name", name, "expected a name of a-z, 0-9, _ and - (up to 32)")
            continue
        if any(h.name == name for h in out):
            r.error(f"{where}.name", name, "named twice")
            continue
        address = entry.get("address", LOCAL)
        if address != LOCAL and not valid_address(address):
            r.error(
                f"{where}.address", address, f"expected {LOCAL!r}, an IP address or a host name"
            )
            continue
        if address != LOCAL and address in addresses:
            r.error(f"{where}.address", address, f"hosts[{addresses[address]}] has it too")
        addresses.setdefault(address, i)
        out.append(Host(name, address))
    return tuple(out) or (DOME_PC,)


def _sim(r: _Reader, doc: dict) -> SimSettings:
    keys = {
        "seed",
        "scenario",
        "ticks",
        "command_timeout",
        "first_command_timeout",
        "exact",
        "soil",
    }
    s = r.section(doc, "sim", keys, required=False)
    d = SimSettings()
    exact = s.get("exact", d.exact)
    if not isinstance(exact, bool):
        r.error("sim.exact", exact, "expected true or false")
        exact = d.exact
    soil = s.get("soil", d.soil)
    try:
        check_soil(soil)
    except SoilError as e:
        r.error("sim.soil", soil, str(e))
        soil = d.soil
    return SimSettings(
        r.number(s, "sim", "seed", d.seed, 0, 2**31 - 1, integer=True),
        r.number(s, "sim", "scenario", d.scenario, 0, 2**31 - 1, integer=True),
        r.number(s, "sim", "ticks", d.ticks, 1, 10**7, integer=True),
        r.number(s, "sim", "command_timeout", d.command_timeout, positive=True),
        r.number(s, "sim", "first_command_timeout", d.first_command_timeout, positive=True),
        exact,
        soil,
    )


def _overrides(r: _Reader, doc: dict) -> dict[str, dict[str, Any]]:
    """``overrides:``: node kind -> {parameter: value}, of kinds and parameters that exist.

    The values are judged when the graph is built, against the node's parameter dataclasses
    and what the graph derives from the site (:class:`excavation_bringup.node_params.NodeParams`).
    """
    from excavation_bringup.kinds import KINDS

    raw = doc.get("overrides", {})
    if not isinstance(raw, dict):
        r.error("overrides", raw, "expected a mapping node -> {parameter: value}")
        return {}
    out = {}
    for node, values in raw.items():
        if node not in KINDS:
            r.error(f"overrides.{node}", values, f"unknown node kind (known: {sorted(KINDS)})")
            continue
        if not isinstance(values, dict):
            r.error(f"overrides.{node}", values, "expected a mapping parameter: value")
            continue
        known = node_parameter_names(node)
        for name, value in values.items():
            if name not in known:
                r.error(f"overrides.{node}.{name}", value, f"{node} has no such parameter")
        out[node] = dict(values)
    return out


def parse_site(text: str, path: str) -> tuple[Site | None, list[SiteError]]:
    """Parse a site file's text; returns the site (``None`` if unusable) and every error."""
    try:
        doc = safe_load_unique(text, path)
    except SiteError as exc:
        return None, [exc]
    if not isinstance(doc, dict):
        return None, [SiteError(path, "<root>", type(doc).__name__, "expected a mapping")]
    r = _Reader(path)
    if doc.get("format") != FORMAT:
        r.error("format", doc.get("format"), f"expected {FORMAT!r}")
    known = {"format", "name", "worksite", "camera", "laser", "robots", "network", "sim"}
    known |= {"overrides", "hosts"}
    for extra in sorted(set(doc) - known):
        r.error(extra, doc[extra], f"unknown section (known: {sorted(known)})")
    site = Site(
        path,
        _worksite(r, doc),
        _camera(r, doc),
        _laser(r, doc),
        _robots(r, doc),
        _network(r, doc),
        _sim(r, doc),
        _overrides(r, doc),
        _hosts(r, doc),
    )
    return site, r.errors


# --- consistency ------------------------------------------------------------------------------


def _beacon_table(site: Site):
    from overhead_localizer.beacons import CONFIG_DIR, load_beacons

    return load_beacons(site.camera.beacons or CONFIG_DIR / "beacons.yaml")


EMULATED_ENCODINGS = ("bgr8", "yuv422", "jpeg")
"""What the emulated camera driver sends (``dome_emulator.camera``)."""


def consistency(site: Site, sim: bool = False, emulated: bool = False) -> list[SiteError]:
    """Every inconsistency of a parsed site (across sections and against the files it names).

    Args:
        site: The parsed site.
        sim: Checked for ``ant-dome up --sim`` (the simulator's camera and laser).
        emulated: Checked for ``ant-dome rehearse`` (the dome's table against the emulated
            drivers: the simulator's LEDs, laser height and camera model; serial blades,
            whose ports the emulated boards replace).
    """
    from blueprint_server.blueprint import resolve_blueprint

    errors: list[SiteError] = []

    def err(where: str, value: object, reason: str) -> None:
        errors.append(SiteError(site.path, where, value, reason))

    w = site.worksite
    try:
        bp = resolve_blueprint(w.blueprint)
    except FieldError as exc:
        err("worksite.blueprint", w.blueprint, f"cannot be loaded: {exc}")
        bp = None
    if bp is not None:
        rows, cols = bp.shape
        if (w.rows, w.cols) != (rows, cols):
            err("worksite.rows/cols", [w.rows, w.cols], f"the blueprint is {rows} x {cols} cells")
        if not math.isclose(w.cell_size, bp.cell_size, rel_tol=1e-9):
            err("worksite.cell_size", w.cell_size, f"the blueprint's is {bp.cell_size} m")
        if not math.isclose(w.soil_unit, bp.height_unit, rel_tol=1e-9):
            err(
                "worksite.soil_unit",
                w.soil_unit,
                f"the blueprint's height_unit is {bp.height_unit} m (the controllers' "
                "height_unit is the soil unit: they would misread every height)",
            )
    errors += _check_camera(site, sim, emulated)
    errors += _check_laser(site, sim, emulated)
    errors += _check_robots(site, sim, emulated)
    errors += _check_hosts(site, emulated)
    return errors


def _check_hosts(site: Site, emulated: bool = False) -> list[SiteError]:
    """Hosts that can reach each other; a rehearsal's in its address range."""
    out = []
    if len(site.hosts) < 2:
        return out
    net = site.network
    if net.discovery_range == "OFF":
        out.append(
            SiteError(site.path, "network.discovery_range", "OFF", "no host would find another")
        )
    elif net.discovery_range == "LOCALHOST":
        for i, h in enumerate(site.hosts):
            if h.address != LOCAL and h.address not in net.static_peers:
                out.append(
                    SiteError(
                        site.path,
                        f"hosts[{i}].address",
                        h.address,
                        "not among network.static_peers: with discovery_range LOCALHOST the "
                        "other hosts would not find it",
                    )
                )
    if emulated:
        from excavation_bringup.virtual_hosts import rehearsal_address_problem

        for i, h in enumerate(site.hosts):
            problem = rehearsal_address_problem(h.address)
            if problem:
                out.append(SiteError(site.path, f"hosts[{i}].address", h.address, problem))
    return out


def _check_camera(site: Site, sim: bool, emulated: bool = False) -> list[SiteError]:
    out = []
    c = site.camera

    def err(where: str, value: object, reason: str) -> None:
        out.append(SiteError(site.path, where, value, reason))

    if not c.calibration:
        err("camera.calibration", c.calibration, "required: the localizer needs the camera model")
    elif c.calibration == SIMULATED:
        if not (sim or emulated):
            err("camera.calibration", c.calibration, "only with --sim: give the dome's file")
    else:
        from overhead_localizer.camera_model import load_model

        try:
            load_model(c.calibration)
        except FieldError as exc:
            same = exc.path == c.calibration and exc.field == "file"
            err("camera.calibration", c.calibration, exc.reason if same else str(exc))
    if c.compressed and not c.image_topic.endswith("/compressed"):
        err(
            "camera.image_topic",
            c.image_topic,
            f"{c.encoding} frames are a CompressedImage stream, named <image topic>/compressed",
        )
    if not c.compressed and c.image_topic.endswith("/compressed"):
        err("camera.encoding", c.encoding, "a .../compressed topic carries jpeg or png")
    if sim and (c.compressed or c.encoding != "bgr8" or c.camera_info_topic):
        err("camera", c.image_topic, "with --sim the synthetic camera sends bgr8 image_raw only")
    if emulated and c.encoding not in EMULATED_ENCODINGS:
        err("camera.encoding", c.encoding, f"the emulated camera sends {list(EMULATED_ENCODINGS)}")
    if c.beacons:
        try:
            _beacon_table(site)
        except FieldError as exc:
            err("camera.beacons", c.beacons, str(exc))
    return out


def _check_laser(site: Site, sim: bool, emulated: bool = False) -> list[SiteError]:
    out = []
    w, las = site.worksite, site.laser
    x, y, z = las.mount
    width, depth = w.cols * w.cell_size, w.rows * w.cell_size
    if not (0 <= x <= width and 0 <= y <= depth):
        out.append(
            SiteError(
                site.path,
                "laser.mount",
                list(las.mount),
                f"is outside the {width} x {depth} m worksite: the laser must look down on it",
            )
        )
    if sim or emulated:
        from excavation_sim.laser import LaserParams

        expected = LaserParams.for_site(w.rows, w.cols, w.cell_size)
        if sim and not all(
            math.isclose(a, b, abs_tol=1e-9) for a, b in zip(las.mount, expected.mount, strict=True)
        ):
            out.append(
                SiteError(
                    site.path,
                    "laser.mount",
                    list(las.mount),
                    f"the simulator's laser is at {list(expected.mount)}",
                )
            )
        if (las.pan_offset, las.tilt_offset, las.roll_offset) != (0.0, 0.0, 0.0):
            out.append(
                SiteError(site.path, "laser.offsets", None, "the simulator's laser has none")
            )
        if not math.isclose(las.robot_height, expected.robot_height):
            out.append(
                SiteError(
                    site.path,
                    "laser.robot_height",
                    las.robot_height,
                    f"the simulator's robots are {expected.robot_height} m tall",
                )
            )
    return out


def _check_robots(site: Site, sim: bool, emulated: bool = False) -> list[SiteError]:
    out = []

    def err(where: str, value: object, reason: str) -> None:
        out.append(SiteError(site.path, where, value, reason))

    try:
        table = _beacon_table(site)
        colours = set(table.colours)
    except FieldError:
        table, colours = None, set()
    sim_pairs = ()
    if sim or emulated:
        from excavation_sim.camera import default_beacons

        sim_pairs = default_beacons().robots
    pairs: dict[tuple[str, str], int] = {}
    ports: dict[str, int] = {}
    drives: dict[str, int] = {}
    for k, robot in enumerate(site.robots):
        where = f"robots[{k}]"
        for colour in robot.leds:
            if table is not None and colour not in colours and colour != "?":
                err(f"{where}.leds", list(robot.leds), f"{colour!r} is not in {sorted(colours)}")
        if robot.leds in pairs:
            err(
                f"{where}.leds",
                list(robot.leds),
                f"the same pair as robots[{pairs[robot.leds]}]: the localizer cannot tell "
                "them apart",
            )
        pairs.setdefault(robot.leds, k)
        if sim_pairs and k < len(sim_pairs) and robot.leds != sim_pairs[k]:
            err(
                f"{where}.leds",
                list(robot.leds),
                f"the simulator's robot {k} carries {list(sim_pairs[k])}",
            )
        if robot.backend == "sim" and not sim:
            err(
                f"{where}.blade.backend",
                robot.backend,
                "only with --sim (the simulator is that blade's board): in the dome give the "
                "serial board's port (a bench without a blade: blade_driver fake_board)",
            )
        if robot.backend == "serial" and robot.port:
            if robot.port in ports:
                err(f"{where}.blade.port", robot.port, f"robots[{ports[robot.port]}] uses it too")
            ports.setdefault(robot.port, k)
        topic = robot.drive_topic_resolved
        if topic in drives:
            err(
                f"{where}.drive_topic",
                robot.drive_topic,
                f"robots[{drives[topic]}] drives {topic} too: two executors would command one base",
            )
        drives.setdefault(topic, k)
        if robot.host and robot.host not in {h.name for h in site.hosts}:
            err(
                f"{where}.host",
                robot.host,
                f"not a host of the site (hosts: {[h.name for h in site.hosts]})",
            )
        if robot.genome != HAND_CODED:
            from ant_controller.genome_io import load_genome

            try:
                load_genome(robot.genome)
            except FieldError as exc:
                if exc.field == "<file>":
                    err(f"{where}.genome", robot.genome, exc.reason)
                else:
                    err(f"{where}.genome", robot.genome, f"cannot be loaded: {exc}")
            except OSError as exc:
                err(f"{where}.genome", robot.genome, f"cannot be read: {exc}")
    if sim_pairs and len(site.robots) > len(sim_pairs):
        err("robots", len(site.robots), f"the simulator paints LEDs on {len(sim_pairs)} robots")
    return out


def node_parameter_names(node: str) -> set[str]:
    """Every parameter node kind ``node`` declares (its parameter dataclasses)."""
    from dataclasses import fields

    from excavation_bringup.kinds import kind

    return {f.name for cls in kind(node).param_classes() for f in fields(cls)}


def check_site(
    path: str | Path, sim: bool = False, emulated: bool = False
) -> tuple[Site | None, list[SiteError]]:
    """Read ``path`` and return the site with every error found (empty: usable).

    ``sim``: for ``ant-dome up --sim``; ``emulated``: for ``ant-dome rehearse``.
    """
    path = str(path)
    try:
        text = read_text_bounded(path, error=SiteError)
    except SiteError as exc:
        return None, [exc]
    site, errors = parse_site(text, path)
    if site is not None:
        errors += consistency(site, sim, emulated)
    return site, errors


def load_site(path: str | Path, sim: bool = False, emulated: bool = False) -> Site:
    """A usable site (``sim`` and ``emulated`` as :func:`check_site`).

    Raises:
        SiteError: The first problem :func:`check_site` finds.
    """
    site, errors = check_site(path, sim, emulated)
    if errors:
        raise errors[0]
    return site


# --- files the nodes read ----------------------------------------------------------------


def beacons_document(site: Site) -> dict[str, Any]:
    """The localizer's LED table for this site: the table's colours, the robots' pairs."""
    table = _beacon_table(site)
    return {
        "height": table.height,
        "spacing": table.spacing,
        "radius": table.radius,
        "colours": {name: list(bgr) for name, bgr in table.colours.items()},
        "robots": [{"front": r.leds[0], "rear": r.leds[1]} for r in site.robots],
    }


def environment(site: Site, domain: int | None = None) -> dict[str, str]:
    """The ROS network of every process of the site, on every host.

    ``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE`` and ``ROS_STATIC_PEERS``
    (:meth:`excavation_common.network.Network.environment`); ``domain`` replaces the site's.
    """
    env = site.network.environment()
    if domain is not None:
        env["ROS_DOMAIN_ID"] = str(domain)
    return env
