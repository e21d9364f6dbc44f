"""``ant-bag recover``: a complete copy of a bag whose recorder was killed mid-recording.

:func:`excavation_bags.reader.open_bag` reads a truncated MCAP file up to its last
complete chunk; :func:`recover_bag` writes those messages, with their topics and offered
QoS, into a new bag that every reader accepts, and notes in ``custom_data.recovered_from``
what was missing. The input is never changed. Pure module: no ``rclpy``.
"""

from __future__ import annotations

from pathlib import Path

from excavation_bags.metadata import PRODUCER
from excavation_bags.reader import Bag, open_bag
from excavation_bags.topics import known_type
from excavation_bags.writer import BagWriter


def recover_bag(path: str | Path, out: str | Path) -> Bag:
    """Write everything readable from ``path`` into a new, complete bag at ``out``.

    Topics of types the tools do not know are left out. Returns the new bag, opened.

    Raises:
        BagError: The input cannot be read or ``out`` exists.
    """
    bag = open_bag(path)
    custom = {k: str(v) for k, v in bag.custom_data.items() if k not in ("producer", "format")}
    if bag.truncated:
        custom["recovered_from"] = f"{bag.mcap.name}: {bag.truncated}"
    with BagWriter(out, custom) as writer:
        if bag.producer != PRODUCER:
            writer.custom_data["producer"] = str(bag.producer or "unknown")
        for t in bag.topics.values():
            if known_type(t.msgtype):
                writer.add_topic(t.name, t.msgtype, t.qos)
        for topic, ts, raw in bag.messages():
            if topic in writer.topics:
                writer.write(topic, ts, raw)
    return open_bag(out)
