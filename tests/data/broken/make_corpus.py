"""Regenerate the broken-input corpus beside this file: ``python make_corpus.py``.

The files are shipped; this script documents how the binary ones were made and rebuilds
them all from the shipped genome and localizer configuration. Each file breaks exactly one
rule; ``tests/test_broken_inputs.py`` lists what each must be refused for.
"""

from __future__ import annotations

import copy
import json
import struct
import zlib
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
BP = "format: ant-blueprint/1\n"


def write(rel: str, content: str | bytes) -> None:
    path = HERE / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")


def png_header_only(width: int, height: int) -> bytes:
    """A PNG whose IHDR claims ``width x height`` with one tiny IDAT (a decoder bomb)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data) & 0xFFFFFFFF
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    # The first rows of a white image; the decoder would need width x height x 3 bytes.
    rows = zlib.compress((b"\x00" + b"\xff" * (3 * width)) * 4, 9)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", rows) + chunk(b"IEND", b"")


def blueprints() -> None:
    pit = "pit: {size: [8, 8], depth: 1}\n"
    write("blueprint/huge_grid.yaml", BP + "grid: [100000000, 100000000]\n" + pit)
    write("blueprint/huge_cells.yaml", BP + "grid: [4000, 4000]\n" + pit)
    write("blueprint/huge_depth.yaml", BP + "pit: {size: [8, 8], depth: 99999999999999999999}\n")
    write("blueprint/huge_pit.yaml", BP + "grid: [16, 16]\npit: {size: [99999999, 8]}\n")
    write("blueprint/huge_dump_band.yaml", BP + "dump_band: 99999999999\n" + pit)
    write("blueprint/tiny_cell_size.yaml", BP + "cell_size: 1.0e-300\n" + pit)
    write("blueprint/huge_float.yaml", BP + "height_unit: 1.0e+999\n" + pit)
    write("blueprint/duplicate_key.yaml", BP + "grid: [16, 16]\ngrid: [32, 32]\n" + pit)
    write("blueprint/duplicate_nested_key.yaml", BP + "pit: {size: [8, 8], depth: 1, depth: 3}\n")
    write("blueprint/deep_nesting.yaml", BP + "pit: " + "[" * 200 + "]" * 200 + "\n")
    lol = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 10)}]\n" for i in range(8)
    )
    write("blueprint/alias_bomb.yaml", BP + lol + pit)
    write("blueprint/truncated.yaml", BP + "grid: [16,\n")
    write("blueprint/wide_rows.yaml", BP + "rows:\n  - '" + "1" * 5000 + "'\n")
    write("blueprint/garbage.yaml", bytes((i * 167 + 13) % 256 for i in range(4096)))
    write("blueprint/huge_image.png", png_header_only(20000, 20000))
    write("blueprint/huge_image.yaml", BP + "image: huge_image.png\nscale: 0.05\n")
    write("blueprint/not_an_image.png", b"this is not a picture\n" * 20)
    write("blueprint/not_an_image.yaml", BP + "image: not_an_image.png\nscale: 0.05\n")
    write(
        "blueprint/huge_image_depth.yaml",
        BP + "image: ok_image.png\nscale: 0.05\nmax_depth: 1.0e+9\n",
    )
    write("blueprint/ok_image.png", png_header_only(64, 64))


def genomes() -> None:
    best = json.loads((ROOT / "genomes/best.json").read_text())
    best["cells"] = best["cells"][:2]  # small files; the broken part is elsewhere
    text = json.dumps(best, indent=1)
    write("genome/truncated.json", text[: len(text) // 2])
    many = copy.deepcopy(best)
    many["cells"] = [{}] * 10_001
    write("genome/huge_gene_count.json", json.dumps(many))
    dup = text.replace('"format": "ant-genome/1",', '"format": "ant-genome/1",\n "format": "x",', 1)
    write("genome/duplicate_key.json", dup)
    nan = copy.deepcopy(best)
    nan["cells"][0]["theta1"] = float("nan")
    write("genome/nan.json", json.dumps(nan))
    huge = copy.deepcopy(best)
    huge["cells"][0]["theta1"] = 1.0
    write("genome/huge_float.json", json.dumps(huge).replace('"theta1": 1.0', '"theta1": 1e999', 1))
    deep = copy.deepcopy(best)
    deep["metadata"] = {"notes": json.loads("[" * 100 + "]" * 100)}
    write("genome/deep_nesting.json", json.dumps(deep))
    team = copy.deepcopy(best)
    team["tissue"]["robots"] = 10**30
    write("genome/huge_robots_gene.json", json.dumps(team))
    write("genome/huge_integer.json", '{"format": ' + "9" * 5000 + "}")
    write("genome/garbage.json", bytes((i * 131 + 7) % 256 for i in range(4096)))


def configs() -> None:
    write("config/unknown_key.yaml", "population: 10\npopulaton: 20\n")
    write("config/huge_population.yaml", "population: 100000000000\n")
    write("config/huge_steps.yaml", "steps: 99999999999999999999\n")
    write("config/negative_seed.yaml", "seed: -1\n")
    write("config/huge_depths.yaml", "depths: [1, 2, 100000]\n")
    write("config/huge_workload.yaml", "population: 10000\nscenarios: 100000\n")
    write("config/duplicate_key.yaml", "population: 10\ngenerations: 5\npopulation: 20\n")
    write("config/broken_blueprint.yaml", "blueprint: tests/data/broken/blueprint/huge_grid.yaml\n")
    write("config/garbage.yaml", bytes((i * 97 + 3) % 256 for i in range(2048)))


def localizer() -> None:
    cfg = ROOT / "ros2_ws/src/overhead_localizer/config"
    beacons = (cfg / "beacons.yaml").read_text()
    write("localizer/beacons_duplicate_key.yaml", beacons + "height: 0.2\n")
    robots = "".join("  - {front: red, rear: green}\n" for _ in range(65))
    head = beacons.split("robots:")[0]
    write("localizer/beacons_too_many_robots.yaml", head + "robots:\n" + robots)
    write("localizer/beacons_garbage.yaml", bytes((i * 53 + 1) % 256 for i in range(2048)))
    camera = (cfg / "camera_sim.yaml").read_text()
    write(
        "localizer/camera_huge_image.yaml",
        camera.replace("image_width: 1280", "image_width: 1000000", 1),
    )
    write("localizer/camera_duplicate_key.yaml", camera + "rms_px: 0.5\n")
    write(
        "localizer/camera_truncated.yaml",
        camera[: camera.index("dist_coeffs")] + "dist_coeffs: [0.1,\n",
    )
    marks = (cfg / "marks_sim.yaml").read_text()
    write("localizer/marks_duplicate_key.yaml", marks + "image_width: 640\n")
    write("localizer/marks_deep_nesting.yaml", "points: " + "[" * 100 + "]" * 100 + "\n")


def maps() -> None:
    header = b"{'descr': '<f8', 'fortran_order': False, 'shape': (100000, 100000), }"
    header += b" " * (63 - len(header) % 64) + b"\n"
    npy = b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header + b"\0" * 64
    write("map/huge_shape.npy", npy)
    write("map/garbage.npy", bytes((i * 29 + 5) % 256 for i in range(1024)))


if __name__ == "__main__":
    blueprints()
    genomes()
    configs()
    localizer()
    maps()
