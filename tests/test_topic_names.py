"""Topic names are checked where they are configured, by rcl's rules (not at first use)."""

from __future__ import annotations

import pytest
from rclpy.expand_topic_name import expand_topic_name
from rclpy.validate_full_topic_name import validate_full_topic_name

from excavation_common.params import ParameterError, validate
from excavation_common.topics import frame_name_problem, topic_name_problem

NAMES = [
    "/a/b", "a", "cmd_vel", "~/x", "/a/{node}", "/_a", "/a/b_", "/overhead/image_raw",
    "/a/b/", "/1abc", "/a/1b", "/a-b", "/a b", "a//b", "/a/~b", "~x", "{a", "/a/{b{c}}",
    "/a/é", "", "/",
]  # fmt: skip


def rcl_accepts(name: str) -> bool:
    """rcl's own verdict: the name expands (in namespace /ns of node n) to a valid one."""
    try:
        full = expand_topic_name(name, "n", "/ns")
        validate_full_topic_name(full)
    except Exception:  # noqa: BLE001 - any refusal of rcl's
        return False
    return True


@pytest.mark.parametrize("name", NAMES)
def test_the_check_agrees_with_rcl(name):
    if "{" in name and rcl_accepts(name.replace("{node}", "n")):
        return  # substitutions other than rcl's known ones are not ours to judge
    assert (topic_name_problem(name) is None) == rcl_accepts(name), name


def test_a_node_parameter_naming_no_topic_is_refused_with_its_field():
    from drive_executor.params import ExecutorParams

    with pytest.raises(ParameterError, match="pose_topic.*starts with a digit"):
        validate(ExecutorParams, {"pose_topic": "/robot_0/1pose"}, "executor")
    assert validate(ExecutorParams, {"pose_topic": "/robot_0/pose"}, "executor")


def test_a_site_naming_no_topic_is_refused_by_the_check(tmp_path):
    from pathlib import Path

    from excavation_bringup import site as sitefile

    config = Path(__file__).resolve().parents[1] / "ros2_ws/src/excavation_bringup/config"
    text = (config / "site_sim.yaml").read_text()
    bad = text.replace("scan_topic: /worksite/scan", "scan_topic: /worksite/2scan", 1)
    assert bad != text
    (tmp_path / "s.yaml").write_text(
        bad.replace("../../../../genomes", str(config.parents[4] / "genomes"))
    )
    _, errors = sitefile.check_site(tmp_path / "s.yaml", sim=True)
    assert any("laser.scan_topic" in str(e) and "starts with a digit" in str(e) for e in errors)


@pytest.mark.parametrize(
    "name, ok",
    [
        ("base_link", True), ("robot_0/base_link", True), ("overhead_camera", True),
        ("laser-1.a", True), ("/base_link", False), ("", False), ("a b", False),
        ("a//b", False), ("odom/", False), ("é", False),
    ],
)  # fmt: skip
def test_frame_ids_follow_tf2(name, ok):
    assert (frame_name_problem(name) is None) == ok, name


def test_a_node_parameter_naming_no_frame_is_refused_with_its_field():
    from dome_emulator.base import BaseParams

    with pytest.raises(ParameterError, match="base_frame_id.*tf2 frame id.*starts with /"):
        validate(BaseParams, {"base_frame_id": "/base_link"}, "base")
    assert validate(BaseParams, {"base_frame_id": "base_link"}, "base")


def test_ant_dome_check_runs_the_nodes_start_up_checks_on_the_graph(tmp_path):
    """The graph ``ant-dome up`` would start passes the nodes' own checks for every shipped
    site in its mode; a node spec with a value its node would refuse is named, as is a
    remapping onto no topic name."""
    import dataclasses
    from pathlib import Path

    from excavation_bringup import site as sitefile
    from excavation_bringup.dome import dome_graph, site_problems, start_problems

    config = Path(__file__).resolve().parents[1] / "ros2_ws/src/excavation_bringup/config"
    for name, hardware in (("site_sim", "sim"), ("site_rehearsal", "emulated")):
        site, errors = sitefile.check_site(
            config / f"{name}.yaml", sim=hardware == "sim", emulated=hardware == "emulated"
        )
        assert not errors
        graph = dome_graph(site, tmp_path / name, hardware)
        assert start_problems(graph, name) == []
    base = next(i for i, n in enumerate(graph.nodes) if n.kind == "emulated_base")
    with pytest.raises(ParameterError, match="base_frame_id = '/base_link': is not a tf2 frame"):
        graph.nodes[base].params.updated(graph.nodes[base].name, base_frame_id="/base_link")
    bad = dataclasses.replace(graph.nodes[base], remaps=(*graph.nodes[base].remaps, "/x:=/2x"))
    graph.nodes[base] = bad
    problems = start_problems(graph, "site.yaml")
    # a site's override of it is refused when the graph is built, naming the field
    text = (
        (config / "site_rehearsal.yaml")
        .read_text()
        .replace("../../../../", str(config.parents[3]) + "/")
    )
    text += "overrides:\n  emulated_base: {base_frame_id: /base_link}\n"
    (tmp_path / "bad.yaml").write_text(text)
    lines = site_problems(tmp_path / "bad.yaml", "emulated")
    assert len(lines) == 1 and "overrides.emulated_base.base_frame_id = '/base_link'" in lines[0]
    assert any("remapping /x to '/2x'" in p for p in problems)
