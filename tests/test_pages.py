"""sheet.png and index.html (``mistyle.pages``)."""

import json

import numpy as np
from PIL import Image

from mistyle.pages import write_grid, write_index, write_sheet


def test_sheet_puts_the_panels_side_by_side_with_text_under(tmp_path):
    red = np.zeros((20, 40, 3), np.float32)
    red[..., 0] = 1.0
    green = np.zeros((16, 16, 3), np.float32)
    green[..., 1] = 1.0
    path = write_sheet(tmp_path / "sheet.png", [("style", red), ("final", green)], ["line one", "line two"], size=64)
    sheet = np.asarray(Image.open(path).convert("RGB"), dtype=np.int32)
    assert sheet.shape[1] == 128 and sheet.shape[0] > 64 + 2 * 14
    top = 18
    assert tuple(sheet[top + 32, 32]) == (255, 0, 0)  # the wide image, fitted into its square
    assert tuple(sheet[top + 5, 5]) == (0, 0, 0)  # letterboxed above it
    assert tuple(sheet[top + 32, 64 + 32]) == (0, 255, 0)
    assert (sheet[top + 64 + 4 :] < 128).any()  # text under the panels


def test_grid_puts_rows_of_labelled_tiles(tmp_path):
    red, blue = np.zeros((8, 8, 3), np.float32), np.zeros((16, 8, 3), np.float32)
    red[..., 0] = blue[..., 2] = 1.0
    path = write_grid(tmp_path / "grid.png", [[(red, "a"), (blue, "b")], [(blue, "c")]], size=32)
    grid = np.asarray(Image.open(path).convert("RGB"), dtype=np.int32)
    label = 14
    assert grid.shape == (2 * (32 + label), 64, 3)
    assert tuple(grid[label + 16, 16]) == (255, 0, 0)
    assert tuple(grid[label + 16, 32 + 16]) == (0, 0, 255)  # the tall tile, fitted into its square
    assert tuple(grid[label + 16, 32 + 2]) == (0, 0, 0)  # letterboxed beside it
    assert tuple(grid[2 * label + 32 + 16, 16]) == (0, 0, 255)
    assert tuple(grid[2 * label + 32 + 16, 32 + 16]) == (255, 255, 255)  # a short row leaves white
    assert (grid[:label] < 128).any()  # labels above the tiles
    jpeg = write_grid(tmp_path / "grid.jpg", [[(red, "a")]], size=32)
    assert Image.open(jpeg).format == "JPEG"


def test_index_links_renders_figures_tables_and_data_relatively(tmp_path):
    render = tmp_path / "smoke__a&b"
    render.mkdir()
    write_sheet(render / "sheet.png", [("x", np.ones((8, 8, 3), np.float32))], [], size=16)
    (render / "report.json").write_text(json.dumps({"rgb_swd": 0.0123, "hue_coverage": 0.5}))
    Image.new("RGB", (4, 4)).save(tmp_path / "curve.png")
    (tmp_path / "fidelity_table.md").write_text("| a | b |\n|---|---|\n| <1> | 2 |\n")
    (tmp_path / "notes.md").write_text("# long notes")
    (tmp_path / "rows.jsonl").write_text("{}\n")
    (tmp_path / ".hidden.png").write_bytes(b"")
    page = write_index(tmp_path, "a <title>", ["made by a test"]).read_text()
    assert "<title>a &lt;title&gt;</title>" in page and "made by a test" in page
    assert "href='smoke__a&amp;b/'" in page and "src='smoke__a&amp;b/sheet.png'" in page and "rgb_swd 0.0123" in page
    assert "src='curve.png'" in page and "&lt;1&gt;" in page  # the table shown, escaped
    assert "href='notes.md'" in page and "href='rows.jsonl'" in page and ".hidden" not in page
    assert str(tmp_path) not in page  # relative links only
