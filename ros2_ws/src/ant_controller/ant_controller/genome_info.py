"""``genome_info``: validate a genome file and summarise the tissue it grows into.

Usage: ``ros2 run ant_controller genome_info best.json [--json]``. Exit code 2 with the
loader's message (file, field, value) when the file is malformed.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter

from ant_controller.errors import GenomeFormatError
from ant_controller.genome_io import load_genome
from ant_controller.layout import BEHAVIOURS
from ant_controller.tissue import compile_tissue, develop


def summarize(path: str) -> dict:
    """Facts about a genome file: gene and neuron counts, layers, outputs, metadata."""
    genome = load_genome(path)
    cells = develop(genome)
    tissue = compile_tissue(genome)
    outputs = Counter(BEHAVIOURS[q] for q in tissue.mn_behaviour if q >= 0)
    return {
        "file": path,
        "genes": genome.n_cells,
        "grown_cells": len(cells),
        "dead_cells": sum(c.dead for c in cells),
        "motor_neurons": tissue.n_motor,
        "decision_neurons": tissue.n_decision,
        "layers": sorted({int(n) for n in tissue.mn_layer}),
        "output_neurons": dict(sorted(outputs.items())),
        "coarse_coding": tissue.coarse_coding,
        "robots_gene": genome.tissue.robots,
        "metadata": genome.metadata,
    }


def main(argv: list[str] | None = None) -> int:
    """Entry point."""
    parser = argparse.ArgumentParser(prog="genome_info", description=__doc__.split("\n\n")[0])
    parser.add_argument("genome", help="ant-genome/1 JSON file")
    parser.add_argument("--json", action="store_true", help="print JSON")
    args = parser.parse_args(argv)
    try:
        info = summarize(args.genome)
    except GenomeFormatError as exc:
        print(f"genome_info: error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(info, indent=1))
    else:
        for key, value in info.items():
            print(f"{key:>17}: {value}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
