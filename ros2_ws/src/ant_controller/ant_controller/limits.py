"""The ANT controller's limits: what a genome file may hold.

Checked while a genome file is read, before the tissue is grown; each error names the file,
the field, the value and the limit. ``docs/reliability.md`` lists every limit of the suite.
"""

from __future__ import annotations

from excavation_common.limits import MAX_NESTING, MAX_ROBOTS

__all__ = [
    "MAX_GENES",
    "MAX_GENOME_BYTES",
    "MAX_HALF_WIDTH",
    "MAX_LAYERS",
    "MAX_NESTING",
    "MAX_ROBOTS",
]

MAX_GENOME_BYTES = 16 << 20
"""Largest genome file (16 MiB; a gene takes about 1 KB written with ``indent=1``)."""
MAX_GENES = 10_000
"""Most cell genes in a genome (the default 17 x 17 x 3 lattice holds 867)."""
MAX_HALF_WIDTH = 64
"""Widest lattice: positions ``l, m`` in ``-64..64``."""
MAX_LAYERS = 3
"""Most motor layers above the sensors (the paper's four layers in all)."""
