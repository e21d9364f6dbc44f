"""``ant-bag diff A B``: two bags of the same run compared topic by topic.

For a re-perception (``ant-bag play --reperceive``), a replay with another genome, or two
recordings of one trial. Per topic present in both bags, by kind:

* **poses** (``geometry_msgs/PoseWithCovarianceStamped``: ``/robot_k/pose``,
  ``/tick/robot_k/pose``): messages matched by header stamp; position error (cm, mean and
  max) and heading error (degrees, max) over the matched pairs, and the stamps only one bag
  has;
* **height maps** (``sensor_msgs/Image`` in ``32FC1``): matched by header stamp; per pair
  the cells that differ by more than ``tolerance``; the most cells and the largest
  difference over all pairs;
* **words** (``std_msgs/UInt16``: ``/robot_k/behaviour``): the n-th word of A against the
  n-th of B; the indices (ticks) that differ;
* anything else: message counts, and how many of the first ``min(count)`` messages are
  byte for byte the same.

A topic in only one bag is listed as such. :func:`diff_bags` returns it all as a mapping;
``same`` is true when nothing differs.
"""

from __future__ import annotations

import math

import numpy as np

from excavation_bags.field_report import header_ns, quaternion_yaw

POSE_TYPE = "geometry_msgs/msg/PoseWithCovarianceStamped"
IMAGE_TYPE = "sensor_msgs/msg/Image"
WORD_TYPE = "std_msgs/msg/UInt16"


def _by_stamp(bag, topic: str) -> dict[int, object]:
    return {
        header_ns(msg.header): msg
        for msg in (bag.decode(topic, raw) for _, _, raw in bag.messages([topic]))
    }


def diff_poses(a, b, topic: str) -> dict:
    """Position and heading errors of ``topic``'s poses matched by header stamp."""
    pa, pb = _by_stamp(a, topic), _by_stamp(b, topic)
    common = sorted(set(pa) & set(pb))
    dist, turn = [], []
    for t in common:
        x, y = pa[t].pose.pose.position, pb[t].pose.pose.position
        dist.append(math.hypot(x.x - y.x, x.y - y.y) * 100.0)
        d = quaternion_yaw(pa[t].pose.pose.orientation) - quaternion_yaw(
            pb[t].pose.pose.orientation
        )
        turn.append(abs(math.degrees(math.atan2(math.sin(d), math.cos(d)))))
    return {
        "kind": "poses",
        "matched": len(common),
        "only_in_a": len(set(pa) - set(pb)),
        "only_in_b": len(set(pb) - set(pa)),
        "position_cm_mean": float(np.mean(dist)) if dist else None,
        "position_cm_max": float(np.max(dist)) if dist else None,
        "heading_deg_max": float(np.max(turn)) if turn else None,
        "same": not (set(pa) ^ set(pb)) and (not dist or max(dist) == 0 and max(turn) == 0),
    }


def diff_height_maps(a, b, topic: str, tolerance: float) -> dict:
    """Cells that differ by more than ``tolerance`` in maps matched by header stamp."""
    from excavation_common.messages import image_to_grid

    ma, mb = _by_stamp(a, topic), _by_stamp(b, topic)
    common = sorted(set(ma) & set(mb))
    most, largest, differing_maps = 0, 0.0, 0
    for t in common:
        ga = image_to_grid(ma[t], "32FC1", topic)
        gb = image_to_grid(mb[t], "32FC1", topic)
        if ga.shape != gb.shape:
            most, differing_maps = max(most, max(ga.size, gb.size)), differing_maps + 1
            continue
        delta = np.abs(ga.astype(np.float64) - gb.astype(np.float64))
        cells = int((delta > tolerance).sum())
        most = max(most, cells)
        largest = max(largest, float(delta.max()) if delta.size else 0.0)
        differing_maps += cells > 0
    return {
        "kind": "height maps",
        "matched": len(common),
        "only_in_a": len(set(ma) - set(mb)),
        "only_in_b": len(set(mb) - set(ma)),
        "maps_differing": differing_maps,
        "most_cells_differing": most,
        "largest_difference": largest,
        "same": not (set(ma) ^ set(mb)) and differing_maps == 0,
    }


def diff_words(a, b, topic: str) -> dict:
    """The n-th word of each bag compared; the indices (ticks) that differ."""
    wa = [int(a.decode(topic, raw).data) for _, _, raw in a.messages([topic])]
    wb = [int(b.decode(topic, raw).data) for _, _, raw in b.messages([topic])]
    differing = [i for i, (x, y) in enumerate(zip(wa, wb, strict=False)) if x != y]
    return {
        "kind": "words",
        "count_a": len(wa),
        "count_b": len(wb),
        "ticks_differing": differing,
        "same": not differing and len(wa) == len(wb),
    }


def diff_raw(a, b, topic: str) -> dict:
    """Counts, and the first ``min(count)`` messages compared byte for byte."""
    ra = [raw for _, _, raw in a.messages([topic])]
    rb = [raw for _, _, raw in b.messages([topic])]
    same = sum(x == y for x, y in zip(ra, rb, strict=False))
    return {
        "kind": "messages",
        "count_a": len(ra),
        "count_b": len(rb),
        "identical": same,
        "same": len(ra) == len(rb) == same,
    }


def diff_bags(a, b, topics: list[str] | None = None, tolerance: float = 1e-6) -> dict:
    """Every topic of ``a`` and ``b`` (or of ``topics``, names or globs) compared.

    Returns ``{"topics": {name: result}, "only_in_a": [...], "only_in_b": [...], "same"}``.
    """
    from excavation_bags.topics import topic_selected

    def chosen(name: str) -> bool:
        return not topics or topic_selected(name, topics)

    names_a = {t for t in a.topics if chosen(t)}
    names_b = {t for t in b.topics if chosen(t)}
    out: dict = {
        "topics": {},
        "only_in_a": sorted(names_a - names_b),
        "only_in_b": sorted(names_b - names_a),
    }
    for name in sorted(names_a & names_b):
        kind = a.topics[name].msgtype
        if kind != b.topics[name].msgtype:
            out["topics"][name] = {
                "kind": "types differ",
                "type_a": kind,
                "type_b": b.topics[name].msgtype,
                "same": False,
            }
        elif kind == POSE_TYPE:
            out["topics"][name] = diff_poses(a, b, name)
        elif kind == IMAGE_TYPE and name.endswith("height_map"):
            out["topics"][name] = diff_height_maps(a, b, name, tolerance)
        elif kind == WORD_TYPE and name.endswith("/behaviour"):
            out["topics"][name] = diff_words(a, b, name)
        else:
            out["topics"][name] = diff_raw(a, b, name)
    out["same"] = (
        not out["only_in_a"]
        and not out["only_in_b"]
        and all(r["same"] for r in out["topics"].values())
    )
    return out


def diff_lines(result: dict) -> list[str]:
    """The comparison as lines of text (``ant-bag diff`` without ``--json``)."""

    def n(v, spec: str = ".2f") -> str:
        return "n/a" if v is None else format(v, spec)

    lines = []
    for name in result["only_in_a"]:
        lines.append(f"{name}: only in A")
    for name in result["only_in_b"]:
        lines.append(f"{name}: only in B")
    for name, r in result["topics"].items():
        mark = "same" if r["same"] else "DIFFERS"
        match r["kind"]:
            case "poses":
                lines.append(
                    f"{name}: {mark}: {r['matched']} poses matched by stamp "
                    f"({r['only_in_a']} only in A, {r['only_in_b']} only in B); position "
                    f"error {n(r['position_cm_mean'])} cm mean, {n(r['position_cm_max'])} cm "
                    f"max; heading {n(r['heading_deg_max'])} deg max"
                )
            case "height maps":
                lines.append(
                    f"{name}: {mark}: {r['matched']} maps matched by stamp, "
                    f"{r['maps_differing']} differ (at most {r['most_cells_differing']} cells, "
                    f"by up to {n(r['largest_difference'], '.4g')})"
                )
            case "words":
                ticks = r["ticks_differing"]
                lines.append(
                    f"{name}: {mark}: {r['count_a']} words in A, {r['count_b']} in B; "
                    f"{len(ticks)} ticks differ" + (f", first {ticks[0]}" if ticks else "")
                )
            case "messages":
                lines.append(
                    f"{name}: {mark}: {r['count_a']} messages in A, {r['count_b']} in B, "
                    f"{r['identical']} identical"
                )
            case _:
                lines.append(f"{name}: DIFFERS: type {r['type_a']} in A, {r['type_b']} in B")
    lines.append("the bags are the same" if result["same"] else "the bags differ")
    return lines
