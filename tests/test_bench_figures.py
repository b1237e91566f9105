"""benchmarks/bench_figures.py's comparison of the two trees' PNGs: which differ, and how."""

from __future__ import annotations

import numpy as np
from PIL import Image

from benchmarks.bench_figures import pixel_differences


def test_the_pngs_that_differ_are_named_with_their_differing_pixels_or_sizes(tmp_path):
    new, old = tmp_path / "new", tmp_path / "old"
    new.mkdir()
    old.mkdir()
    white = np.full((10, 20, 3), 255, np.uint8)
    dotted = white.copy()
    dotted[2, 3] = dotted[5, 7] = (0, 0, 0)
    for folder, same, moved, resized in ((new, white, dotted, white), (old, white, white, white[:, :15])):
        Image.fromarray(same).save(folder / "same.png")
        Image.fromarray(moved).save(folder / "moved.png")
        Image.fromarray(resized).save(folder / "resized.png")
    assert pixel_differences(new, old) == {"moved.png": "2 of 200 pixels", "resized.png": "size 20x10 against 15x10"}
