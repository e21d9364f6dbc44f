"""The field figures of a continuous or dome run, from its bag (``ant-bag report``).

What the paper's dome trial measured of its robots, per robot: the track from the
localiser's poses (``/robot_k/pose``), how far each goal of the drive executor ended from
the lattice it drives on (drift: the robot's centre against the nearest cell corner, where
every grid pose puts it, and its heading against the nearest right angle), the camera
frames in which the localiser gave it no pose (lost track: how many, and the longest run
in seconds), its stuck events (the executor's U1, ``/robot_k/stuck`` true), the goals it
aborted (``/robot_k/drive/status``) and the primitives it aborted (the executor's
``primitives_aborted`` on ``/diagnostics``, where recorded); and for the team, the wall
time per tick (``/team/tick``). ``tracks.png`` draws the tracks with each goal's end.

Times are the bag's (each message's source stamp); a pose and the frame it came from carry
the same header stamp, which is how frames without a pose are found.
"""

from __future__ import annotations

import math
import re

import numpy as np

POSE = re.compile(r"^/robot_(\d+)/pose$")
CAMERA_TOPICS = ("/overhead/image_raw/compressed", "/overhead/image_raw")


def header_ns(header) -> int:
    """A message header's stamp in nanoseconds."""
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def quaternion_yaw(q) -> float:
    """The yaw (rad) of an orientation quaternion, as the executors and localiser read it."""
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def field_robots(bag) -> list[int]:
    """Robots with both poses and a drive executor's statuses in the bag."""
    return sorted(
        int(m.group(1))
        for t in bag.topics
        if (m := POSE.match(t)) and f"/robot_{m.group(1)}/drive/status" in bag.topics
    )


def field_figures(bag, cell_size: float, tracks: dict | None = None) -> dict:
    """Per robot and for the team: the figures of the module docstring (JSON-ready).

    ``cell_size`` (m) is the lattice the executors drive on (``/worksite/map_info``);
    ``tracks``, if given, gets each robot's track as an ``[n, 2]`` array of x, y (m).
    """
    out: dict = {"robots": {}, "cell_size": cell_size}
    frames = _frame_stamps(bag)
    aborted = _primitives_aborted(bag)
    for k in field_robots(bag):
        out["robots"][str(k)] = _robot(bag, k, cell_size, frames, tracks)
        out["robots"][str(k)]["primitives_aborted"] = aborted.get(k)
    ticks = []
    if "/team/tick" in bag.topics:
        ticks = [t * 1e-9 for _, t, _ in bag.messages(["/team/tick"])]
    gaps = np.diff(ticks) if len(ticks) > 1 else np.zeros(0)
    out["ticks"] = {
        "count": len(ticks),
        "wall_mean_s": float(gaps.mean()) if gaps.size else None,
        "wall_median_s": float(np.median(gaps)) if gaps.size else None,
        "wall_max_s": float(gaps.max()) if gaps.size else None,
    }
    return out


def _frame_stamps(bag) -> list[int]:
    for topic in CAMERA_TOPICS:
        if topic in bag.topics:
            return [header_ns(bag.decode(topic, raw).header) for _, _, raw in bag.messages([topic])]
    return []


def _robot(bag, k: int, cell_size: float, frames: list[int], tracks: dict | None) -> dict:
    from drive_executor.goals import ABORTED, TERMINAL

    ns = f"/robot_{k}"
    track = []  # (bag time s, header stamp ns, x, y, yaw)
    for _, t, raw in bag.messages([f"{ns}/pose"]):
        msg = bag.decode(f"{ns}/pose", raw)
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        track.append((t * 1e-9, header_ns(msg.header), p.x, p.y, quaternion_yaw(q)))
    ends, aborted, seen = [], 0, set()
    for _, t, raw in bag.messages([f"{ns}/drive/status"]):
        msg = bag.decode(f"{ns}/drive/status", raw)
        # excavation_interfaces/DriveStatus, or a bag from before it: action_msgs/GoalStatus
        goal = getattr(msg, "goal", None)
        which = int(goal.tick) if goal is not None else bytes(msg.goal_info.goal_id.uuid)
        key = (which, int(msg.status))
        if int(msg.status) in TERMINAL and key not in seen:
            seen.add(key)
            ends.append(t * 1e-9)
            aborted += int(msg.status) == ABORTED
    drift, turn, end_points = [], [], []
    times = np.array([p[0] for p in track])
    for te in ends:  # the first pose after the goal ended: where the robot stopped
        i = int(np.searchsorted(times, te)) if times.size else 0
        if i >= len(track):
            continue
        _, _, x, y, yaw = track[i]
        end_points.append((float(te), float(x), float(y)))
        cx, cy = round(x / cell_size) * cell_size, round(y / cell_size) * cell_size
        drift.append(math.hypot(x - cx, y - cy) * 100.0)
        right = round(yaw / (math.pi / 2)) * (math.pi / 2)
        turn.append(abs(math.degrees(yaw - right)))
    stuck = 0
    if f"{ns}/stuck" in bag.topics:
        stuck = sum(
            bool(bag.decode(f"{ns}/stuck", raw).data) for _, _, raw in bag.messages([f"{ns}/stuck"])
        )
    stamps = {p[1] for p in track}
    lost = [f for f in frames if f not in stamps]
    run = longest = 0.0
    period = float(np.median(np.diff(frames))) * 1e-9 if len(frames) > 1 else 0.0
    for f in frames:
        run = run + period if f not in stamps else 0.0
        longest = max(longest, run)
    xy = np.array([(p[2], p[3]) for p in track]).reshape(-1, 2)
    if tracks is not None:
        tracks[str(k)] = xy
    return {
        "poses": len(track),
        "track_m": float(np.hypot(*np.diff(xy, axis=0).T).sum()) if len(xy) > 1 else 0.0,
        "goals_ended": len(ends),
        "goals_aborted": aborted,
        "stuck_events": stuck,
        "drift_cm_mean": float(np.mean(drift)) if drift else None,
        "drift_cm_max": float(np.max(drift)) if drift else None,
        "heading_error_deg_max": float(np.max(turn)) if turn else None,
        "frames": len(frames),
        "frames_without_pose": len(lost) if frames else None,
        "longest_lost_s": longest if frames else None,
        "goal_ends": end_points,
    }


def _primitives_aborted(bag) -> dict[int, int]:
    """Per robot, its executor's last ``primitives_aborted`` on ``/diagnostics``.

    Read once for all robots; a robot whose executor never reported is absent.
    """
    last: dict[int, int] = {}
    if "/diagnostics" not in bag.topics:
        return last
    name = re.compile(r"robot_(\d+)/executor$")
    for _, _, raw in bag.messages(["/diagnostics"]):
        for status in bag.decode("/diagnostics", raw).status:
            m = name.search(status.name)
            if m:
                for kv in status.values:
                    if kv.key == "primitives_aborted":
                        last[int(m.group(1))] = int(kv.value)
    return last


def plot_tracks(figures: dict, tracks: dict, path) -> None:
    """``tracks.png``: each robot's track (x, y in the map frame) and its goals' ends."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 5.0), dpi=110)
    for k, robot in figures["robots"].items():
        xy = tracks.get(k, np.zeros((0, 2)))
        line = ax.plot(xy[:, 0], xy[:, 1], lw=0.8, label=f"robot {k}")[0]
        ends = np.array([(e[1], e[2]) for e in robot["goal_ends"]]).reshape(-1, 2)
        ax.plot(ends[:, 0], ends[:, 1], "o", ms=3, color=line.get_color())
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("tracks (localiser) and goal ends (dots)")
    ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
