"""ANT controller: genome, tissue network, sensing and behaviours (no rclpy in the core).

Importing the package points numba's on-disk cache at a folder keyed by a hash of the
sources of every package whose kernels call each other (ant_controller, excavation_sim,
ant_evolution and its ``baselines``, whose network decisions the episode kernel inlines).
numba checks only the file of the function it caches, so without this a kernel compiled
against an older version of a kernel in another file would be reused. Set
``NUMBA_CACHE_DIR`` to choose the folder yourself.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
from pathlib import Path

import numba

KERNEL_SOURCES = {
    "ant_controller": ("*.py",),
    "excavation_sim": ("*.py",),
    "ant_evolution": ("*.py", "baselines/*.py"),
}
"""The source files, per package, whose numba kernels call each other (hashed together)."""


def source_hash() -> str:
    """The hash of :data:`KERNEL_SOURCES` (and numba's version) that names the cache folder."""
    digest = hashlib.sha256(numba.__version__.encode())
    for name, patterns in KERNEL_SOURCES.items():
        spec = importlib.util.find_spec(name) if name != __name__ else __spec__
        if spec is None or not spec.submodule_search_locations:
            continue
        for location in spec.submodule_search_locations:
            for pattern in patterns:
                for path in sorted(Path(location).glob(pattern)):
                    digest.update(str(path.relative_to(location)).encode())
                    digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


if not os.environ.get("NUMBA_CACHE_DIR"):
    _base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    numba.config.CACHE_DIR = str(_base / "ant-excavation" / "numba" / source_hash())
