"""mistyle-preview in a real browser: headless Chromium (Debian's) driven by Playwright.

``make test-browser`` (marker ``browser``; it installs Debian's ``chromium`` and the ``browser`` extra).
A server is started on a free port with the bundled smoke and two held-out styles; the page must show
the medium, and a style click, a strength change, a mix, a zoom and an orbit drag must each change the
picture; an invalid upload shows an error and the page goes on working; a valid upload becomes a
style. With the default output's settings, the page switches to the look the final render fits.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.browser

ROOT = Path(__file__).resolve().parent.parent
CHROMIUM = os.environ.get("MISTYLE_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
STYLES = ("hokusai_great_wave.jpg", "van_gogh_starry_night.jpg")
FRAME_TIMEOUT_MS = 60_000

if not Path(CHROMIUM).exists():
    pytest.skip(f"no Chromium at {CHROMIUM} (make test-browser installs Debian's)", allow_module_level=True)
playwright = pytest.importorskip("playwright.sync_api", reason="make test-browser installs Playwright")


def start_server(folder: Path, render_options: str):
    """A mistyle-preview process on a free port over ``STYLES`` and a sequence of an empty frame (before a
    simulation's emitter starts) and two frames of the bundled smoke: the process and its URL."""
    from mistyle.files import load_density

    styles, frames = folder / "styles", folder / "frames"
    styles.mkdir()
    frames.mkdir()
    for name in STYLES:
        shutil.copy(ROOT / "mistyle" / "data" / "heldout_styles" / name, styles / name)
    density = load_density(ROOT / "examples" / "smoke_64.vol")
    np.save(frames / "frame_0000.npy", np.zeros_like(density))
    np.save(frames / "frame_0001.npy", density)
    np.save(frames / "frame_0002.npy", np.ascontiguousarray(density[:, :, ::-1]))  # a third, mirrored frame
    process = subprocess.Popen(
        [sys.executable, "-m", "mistyle.preview", "--density", str(frames), "--styles", str(styles),
         "--port", "0", "--out", str(folder / "out"), "--render-options", render_options],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    line = process.stdout.readline()
    match = re.search(r"http://[\d.]+:\d+/", line)
    assert match, line + (process.stdout.read() if process.poll() is not None else "")
    return process, match.group(0)


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """A preview whose final render fits no look (``--refine 0``), so each control change shows one
    albedo: its URL and output folder."""
    folder = tmp_path_factory.mktemp("preview")
    process, url = start_server(folder, "--refine 0 --res 32 --spp 2 --look-steps 2")
    yield url, folder / "out"
    process.terminate()
    assert process.wait(timeout=30) == 143  # SIGTERM, as every command reports it
    assert "mistyle-preview: terminated: the preview server stopped" in process.stdout.read()


@pytest.fixture(scope="module")
def page(server):
    with playwright.sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1100, "height": 900})
        page.goto(server[0])
        page.wait_for_function("window.mistyle.lastFast !== undefined", timeout=FRAME_TIMEOUT_MS)
        yield page
        browser.close()


def last_fast(page) -> tuple[float, np.ndarray]:
    frame = page.evaluate("window.mistyle.lastFast")
    return frame["at"], np.asarray(frame["digest"])


def after(page, action) -> np.ndarray:
    """The digest of the first fast-layer frame drawn after ``action()``."""
    before, _ = last_fast(page)
    action()
    page.wait_for_function(f"window.mistyle.lastFast.at > {before}", timeout=FRAME_TIMEOUT_MS)
    page.wait_for_timeout(200)  # a drag or slider sends several messages: take the settled frame
    return last_fast(page)[1]


def changed(first: np.ndarray, second: np.ndarray) -> float:
    return float(np.abs(first - second).mean())


def test_the_medium_is_visible(page, tmp_path):
    page.locator("canvas").screenshot(path=tmp_path / "canvas.png")
    from PIL import Image

    pixels = np.asarray(Image.open(tmp_path / "canvas.png").convert("RGB"), np.float32)
    assert (pixels.max(axis=-1) > 40).mean() > 0.05  # the plume covers a good part of the view
    assert page.locator("#styles img").count() == len(STYLES)


def test_controls_change_the_picture(page):
    _, start = last_fast(page)
    styled = after(page, lambda: page.locator("#styles img").nth(1).click())
    assert changed(start, styled) > 2.0, "a style click"
    weaker = after(page, lambda: (page.locator("#strength").focus(), page.keyboard.press("Home")))
    assert changed(styled, weaker) > 2.0, "strength 0"
    after(page, lambda: (page.locator("#strength").focus(), page.keyboard.press("End")))
    mixed = after(page, lambda: page.locator("#mix-with").select_option(label=STYLES[0]))
    assert changed(styled, mixed) > 1.0, "a mix of the two styles"
    box = page.locator("canvas").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2

    def drag():
        page.mouse.move(x, y)
        page.mouse.down()
        for step in range(1, 11):
            page.mouse.move(x + 15 * step, y + 3 * step)
            page.wait_for_timeout(20)
        page.mouse.up()

    orbited = after(page, drag)
    assert changed(mixed, orbited) > 2.0, "an orbit drag"
    zoomed = after(page, lambda: (page.mouse.move(x, y), page.mouse.wheel(0, 600)))
    assert changed(orbited, zoomed) > 2.0, "zooming out"


def test_a_bad_upload_shows_an_error_and_the_page_goes_on(page, tmp_path):
    bad = tmp_path / "not_a_picture.png"
    bad.write_text("this is not an image")
    page.locator("#upload").set_input_files(str(bad))
    page.wait_for_function("document.getElementById('error').textContent.length > 0", timeout=30_000)
    assert "not_a_picture.png" in page.locator("#error").inner_text()
    _, before = last_fast(page)
    box = page.locator("canvas").bounding_box()
    zoomed_in = after(page, lambda: (page.mouse.move(box["x"] + 10, box["y"] + 10), page.mouse.wheel(0, -600)))
    assert changed(before, zoomed_in) > 2.0
    again = after(page, lambda: page.locator("#mix-with").select_option(value=""))
    assert changed(zoomed_in, again) > 1.0
    good = ROOT / "examples" / "style_marble.png"
    page.locator("#upload").set_input_files(str(good))
    page.wait_for_function(f"document.querySelectorAll('#styles img').length === {len(STYLES) + 1}", timeout=60_000)
    assert page.locator("#error").inner_text() == ""


def test_the_frame_slider_shows_another_frame(page):
    assert page.locator("#frame-row").is_visible()
    # The page starts on the first frame that holds medium, and its slider says so.
    assert page.locator("#frame").input_value() == "1" and page.locator("#frame-value").inner_text() == "1"
    _, before = last_fast(page)
    other = after(page, lambda: (page.locator("#frame").focus(), page.keyboard.press("End")))
    assert changed(before, other) > 1.0
    empty = after(page, lambda: (page.locator("#frame").focus(), page.keyboard.press("Home")))
    assert np.abs(empty).max() < 2.0  # the empty frame: nothing but the background
    after(page, lambda: (page.locator("#frame").focus(), page.keyboard.press("ArrowRight")))


def test_final_output_and_a_look_from_the_page(page, server):
    _, out = server
    page.locator("#render-final").click()
    page.wait_for_function("document.getElementById('jobs').textContent.includes('written to')", timeout=180_000)
    written = Path(page.locator("#jobs").inner_text().split("written to ", 1)[1].strip())
    assert written.parent == out and (written / "report.json").is_file() and (written / "sheet.png").is_file()
    assert not page.locator("#look-row").is_visible()
    page.locator("#save-look").click()
    page.wait_for_function("!document.getElementById('look-row').hidden", timeout=180_000)
    assert list(out.glob("*.look"))
    _, before = last_fast(page)
    looked = after(page, lambda: page.locator("#look").check())
    assert changed(before, looked) > 0.5


def test_the_page_switches_to_the_look_the_final_render_writes(page, tmp_path):
    """With the default output's settings the page shows the network at once, fits the final render's
    look in the background, shows it and says so; a new style starts again from its network."""
    process, url = start_server(tmp_path, "--res 32 --spp 2 --look-steps 3")
    try:
        page = page.context.browser.new_page(viewport={"width": 1100, "height": 900})  # the other tests' browser
        try:
            page.goto(url)
            page.wait_for_function("window.mistyle.stats.looksShown === 1", timeout=FRAME_TIMEOUT_MS * 3)
            page.wait_for_timeout(300)  # the look's frame, sent before the fit's last message, is drawn
            assert page.evaluate("window.mistyle.shows") == "look"
            assert page.locator("#image-kind").inner_text().startswith("the look")
            assert "look fitted in" in page.locator("#fit").inner_text()
            fit = page.evaluate("window.mistyle.fit")
            assert fit["first_look_ms"] >= 1000 * fit["seconds"] > 0
            _, looked = last_fast(page)
            drawn = page.evaluate("window.mistyle.stats.fast")
            page.locator("#styles img").nth(1).click()
            page.wait_for_function(
                f"window.mistyle.shows === 'network' && window.mistyle.stats.fast > {drawn}", timeout=FRAME_TIMEOUT_MS
            )
            _, network = last_fast(page)
            page.wait_for_function("window.mistyle.stats.looksShown === 2", timeout=FRAME_TIMEOUT_MS * 3)
            page.wait_for_timeout(300)
            _, second = last_fast(page)
            assert changed(network, second) > 0.5 and changed(looked, second) > 1.0
        finally:
            page.close()
    finally:
        process.terminate()
        process.wait(timeout=30)
