"""Recorder and player parameters: declared with ranges, bad values end in one line + exit 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from rclpy.parameter import Parameter

from excavation_bags.cli import main as ant_bag
from excavation_bags.player_node import PlayerParams
from excavation_bags.recorder_node import RecorderNode, RecorderParams
from excavation_common.params import specs

SAMPLE = Path(__file__).resolve().parents[1] / "bags" / "sample"


@pytest.mark.parametrize(
    "command, setting, reason",
    [
        ("record", "flush_period:=0.0", "flush_period"),
        ("record", "depth:=0", "depth"),
        ("record", "depth:=lots", "depth"),
        ("record", "image_codec:=gif", "must be one of jpeg, png, none"),
        ("record", "jpeg_quality:=101", "jpeg_quality"),
        ("play", "rate:=0.0", "rate"),
        ("play", "lockstep_timeout:=-1.0", "lockstep_timeout"),
    ],
)
def test_bad_value_at_start_is_one_line_and_exit_code_2(
    tmp_path, capsys, domain, command, setting, reason
):
    out = tmp_path / "rec"
    where = ["--out", str(out)] if command == "record" else [str(SAMPLE)]
    argv = [command, *where, "--domain", str(domain), "--ros-args", "-p", setting]
    assert ant_bag(argv) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("ant-bag: error: ") and reason in lines[0]
    assert setting.split(":=")[0] in lines[0]
    assert not out.exists()  # nothing is recorded with a bad parameter


def test_bad_value_in_a_real_process(tmp_path, ros_env):
    cmd = [sys.executable, "-m", "excavation_bags.cli", "record", "--out", str(tmp_path / "r")]
    proc = subprocess.run(
        [*cmd, "--ros-args", "-p", "flush_period:=-1.0"],
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "flush_period" in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr


def test_out_is_required(ros):
    from excavation_common.params import ParameterError

    with pytest.raises(ParameterError, match="out = '': required"):
        RecorderNode(context=ros.context)


def test_runtime_changes_are_applied_or_rejected_with_a_reason(ros, tmp_path):
    node = ros.add(
        RecorderNode(
            context=ros.context,
            parameter_overrides=[Parameter("out", value=str(tmp_path / "rec"))],
        )
    )
    try:
        (ok,) = node.set_parameters([Parameter("jpeg_quality", value=50)])
        assert ok.successful and node.params.jpeg_quality == 50
        (bad,) = node.set_parameters([Parameter("jpeg_quality", value=500)])
        assert not bad.successful and bad.reason and node.params.jpeg_quality == 50
        (ro,) = node.set_parameters([Parameter("image_codec", value="png")])
        assert not ro.successful and "read-only" in ro.reason.lower()
        assert node.params.image_codec == "jpeg"
    finally:
        node.close()


@pytest.mark.parametrize("cls", [RecorderParams, PlayerParams])
def test_every_parameter_has_a_description_and_numbers_a_range(cls):
    import dataclasses

    for f in dataclasses.fields(cls):
        spec = specs(cls)[f.name]
        assert spec.description, f.name
        if type(f.default) in (int, float):
            assert spec.low is not None and spec.high is not None, f.name
