"""``--site SITE`` for the tools that join a running dome: the site's domain and discovery."""

from __future__ import annotations

import os

import pytest

from excavation_common.errors import FieldError
from excavation_common.network import Network, site_network, use_site_network


def _site(tmp_path, network: str) -> str:
    path = tmp_path / "site.yaml"
    path.write_text(f"format: ant-site/1\n{network}")
    return str(path)


def test_the_network_section_is_read_with_defaults(tmp_path):
    assert site_network(_site(tmp_path, "network: {domain: 42, discovery_range: SUBNET}\n")) == (
        Network(42, "SUBNET")
    )
    assert site_network(_site(tmp_path, "")) == Network(0, "LOCALHOST")
    env: dict[str, str] = {}
    use_site_network(_site(tmp_path, "network: {domain: 7}\n"), env)
    assert env == {
        "ROS_DOMAIN_ID": "7",
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "ROS_STATIC_PEERS": "",
    }
    peers = "network: {static_peers: [198.18.0.2, robot-1.lan]}\n"
    use_site_network(_site(tmp_path, peers), env)
    assert env["ROS_STATIC_PEERS"] == "198.18.0.2;robot-1.lan"
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    off = "network: {discovery_range: OFF}\n"  # YAML 1.1 reads an unquoted OFF as false
    assert site_network(_site(tmp_path, off)).discovery_range == "OFF"


@pytest.mark.parametrize(
    ("network", "field"),
    [
        ("network: {domain: 300}\n", "network.domain"),
        ("network: {domain: true}\n", "network.domain"),
        ("network: {discovery_range: WAN}\n", "network.discovery_range"),
        ("network: [1, 2]\n", "network"),
        ("network: {static_peers: 198.18.0.2}\n", "network.static_peers"),
        ("network: {static_peers: ['198.18.0.2', 'not a host']}\n", "network.static_peers"),
        ("network: {discovery_range: OFF, static_peers: [198.18.0.2]}\n", "network.static_peers"),
    ],
)
def test_a_bad_network_names_file_field_and_value(tmp_path, network, field):
    path = _site(tmp_path, network)
    with pytest.raises(FieldError) as err:
        site_network(path)
    assert err.value.path == path and err.value.field == field


def test_ant_operator_and_ant_bag_take_the_site(tmp_path, capsys, monkeypatch):
    from excavation_bags.cli import main as bag_main
    from team_supervisor.operator import main as operator_main

    bad = _site(tmp_path, "network: {domain: 999}\n")
    assert operator_main(["--site", bad, "status"]) == 2
    assert "network.domain = 999" in capsys.readouterr().err
    assert bag_main(["play", str(tmp_path / "no_bag"), "--site", bad]) == 2
    assert "network.domain = 999" in capsys.readouterr().err
    monkeypatch.setenv("ROS_DOMAIN_ID", "0")
    good = _site(tmp_path, "network: {domain: 17, discovery_range: LOCALHOST}\n")
    assert bag_main(["play", str(tmp_path / "no_bag"), "--site", good]) == 2  # no bag there
    assert os.environ["ROS_DOMAIN_ID"] == "17"
