"""Re-perception: a run's sensor data through a fresh localiser and mapper (``--reperceive``).

``ant-bag play BAG --reperceive --run-dir RUN --out NEW`` plays only what the dome's sensors
gave (the simulator's ``/clock`` where recorded, camera frames, laser scans and mount
states, the robots' IMU and blade states, the blueprint and map info, the team's enable
flags) in time into a :class:`~overhead_localizer.localizer_node.LocalizerNode` and a
:class:`~terrain_mapper.mapper_node.MapperNode` started here with the run's parameter files
(``RUN/params/localizer.yaml`` and ``mapper.yaml``, which ``ant-dome`` writes; either may be
replaced with ``--localizer-params`` / ``--mapper-params``, edited to try other
parameters), and records what they publish (``/robot_k/pose``, ``/worksite/height_map``)
into ``NEW``. ``ant-bag diff BAG NEW --topics '/robot_*/pose' /worksite/height_map`` then
says how far the new perception is from the recorded one.
"""

from __future__ import annotations

from pathlib import Path

from excavation_bags.errors import BagError

SENSOR_TOPICS = [
    "/clock",
    "/overhead/image_raw/compressed",
    "/overhead/image_raw",
    "/overhead/camera_info",
    "/worksite/scan",
    "/worksite/laser_mount/joint_states",
    "/robot_*/imu",
    "/robot_*/blade/joint_states",
    "/blueprint/*",
    "/worksite/map_info",
    "/robot_*/enabled",
]
"""What a re-perception plays: the sensors, not the perception's own outputs."""

OUTPUTS = ["/robot_*/pose", "/worksite/height_map"]
"""What it records from the fresh localiser and mapper."""


class ReperceptionError(BagError):
    """A parameter file of the localiser or mapper is missing."""


def parameter_files(
    run_dir: str | None, localizer: str | None, mapper: str | None
) -> tuple[Path, Path]:
    """The localiser's and mapper's parameter files: given, else the run directory's.

    Raises:
        ReperceptionError: Neither given nor in ``RUN/params``.
    """
    out = []
    for name, given in (("localizer", localizer), ("mapper", mapper)):
        path = (
            Path(given)
            if given
            else (Path(run_dir) / "params" / f"{name}.yaml" if run_dir else None)
        )
        if path is None or not path.is_file():
            raise ReperceptionError(
                str(path or "-"),
                f"{name} parameters",
                str(path) if path else "",
                f"give --run-dir RUN (ant-dome's run directory, RUN/params/{name}.yaml) or "
                f"--{name}-params FILE",
            )
        out.append(path.resolve())
    return out[0], out[1]


def reperceive_nodes(bag, out: str, context, localizer_params, mapper_params, rate: float = 1.0):
    """The player, the fresh localiser and mapper, and the recorder of a re-perception.

    Returns ``(player, [localizer, mapper, recorder])``; spin them together until the
    player finished, then close the recorder (it finishes ``out``).
    """
    from rclpy.parameter import Parameter

    from excavation_bags.player_node import PlayerNode
    from excavation_bags.recorder_node import RecorderNode
    from overhead_localizer.localizer_node import LocalizerNode
    from terrain_mapper.mapper_node import MapperNode

    recorder = RecorderNode(
        context=context,
        parameter_overrides=[
            Parameter("out", value=str(out)),
            Parameter("topics", value=OUTPUTS),
        ],
    )
    localizer = LocalizerNode(
        context=context, cli_args=["--ros-args", "--params-file", str(localizer_params)]
    )
    mapper = MapperNode(
        context=context, cli_args=["--ros-args", "--params-file", str(mapper_params)]
    )
    player = PlayerNode(
        bag,
        context=context,
        parameter_overrides=[
            Parameter("topics", value=SENSOR_TOPICS),
            Parameter("rate", value=float(rate)),
            Parameter("delay", value=2.0),
        ],
    )
    return player, [localizer, mapper, recorder]
