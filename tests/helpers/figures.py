"""What a written figure must be: a PNG that decodes, of a plotted size, not blank."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np


def assert_figure(path: Path, min_width: int = 300, min_height: int = 200) -> np.ndarray:
    """Decode ``path`` (PNG), check its size and that it holds more than one colour.

    Returns the decoded image (BGR) for further checks.
    """
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert image is not None, f"{path}: not a decodable image"
    height, width = image.shape[:2]
    assert width >= min_width and height >= min_height, f"{path}: {width} x {height} pixels"
    assert image.reshape(-1, 3).std(axis=0).max() > 1.0, f"{path}: one colour only"
    return image
