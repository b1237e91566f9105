"""reporting.png: a figure's pixels written as a PNG that Pillow (an independent decoder) reads back
as the same pixels, with the resolution Pillow itself records."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from reporting.png import up_filtered, write_png


def _image(rows: int, columns: int, channels: int) -> np.ndarray:
    rng = np.random.default_rng(7)
    pixels = np.full((rows, columns, channels), 255, np.uint8)
    pixels[rows // 3 :, : columns // 2] = rng.integers(0, 256, (rows - rows // 3, columns // 2, channels))
    return pixels


@pytest.mark.parametrize("channels, mode", [(3, "RGB"), (4, "RGBA")])
def test_a_written_png_reads_back_as_the_same_pixels(tmp_path, channels, mode):
    pixels = _image(37, 53, channels)
    with Image.open(write_png(tmp_path / "a.png", pixels, 110)) as image:
        assert image.mode == mode and np.array_equal(np.asarray(image), pixels)


def test_the_rgb_view_of_a_cropped_rgba_buffer_is_written_as_it_is(tmp_path):
    """As reporting.plots hands it over: the RGB channels of a crop of the renderer's RGBA buffer."""
    buffer = _image(60, 80, 4)
    view = buffer[5:50, 7:71, :3]
    with Image.open(write_png(tmp_path / "a.png", view, 110)) as image:
        assert np.array_equal(np.asarray(image), view)


def test_the_resolution_is_recorded_as_pillow_records_it(tmp_path):
    pixels = _image(8, 8, 3)
    Image.fromarray(pixels).save(tmp_path / "pillow.png", dpi=(110, 110))
    with (
        Image.open(write_png(tmp_path / "ours.png", pixels, 110)) as ours,
        Image.open(tmp_path / "pillow.png") as theirs,
    ):
        assert ours.info["dpi"] == theirs.info["dpi"]


def test_the_up_filter_is_each_byte_minus_the_byte_above_modulo_256():
    pixels = np.array([[[1, 2, 3], [250, 0, 9]], [[0, 2, 255], [4, 5, 6]]], np.uint8)
    scanlines = up_filtered(pixels)
    assert scanlines.tolist() == [[2, 1, 2, 3, 250, 0, 9], [2, 255, 0, 252, 10, 5, 253]]


def test_an_image_that_is_not_8_bit_rgb_or_rgba_is_refused(tmp_path):
    with pytest.raises(ValueError, match="expected a \\(rows, columns, 3 or 4\\) uint8 image"):
        write_png(tmp_path / "a.png", np.zeros((4, 4, 2), np.uint8), 110)
    with pytest.raises(ValueError, match="uint8"):
        write_png(tmp_path / "a.png", np.zeros((4, 4, 3), np.float64), 110)
