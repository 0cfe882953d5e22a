"""mistyle-preview's frame rate and latencies, measured in the browser (headless Chromium, Playwright).

    make test-browser          # once: Debian's chromium and Playwright
    python experiments/bench_preview.py [--seconds 10] [--res 256]

It starts ``mistyle-preview`` on the bundled smoke (64^3) with two held-out styles, opens the page,
and measures, in the page's own clock (``performance.now``):

* **orbit frame rate**: fast-layer frames received and drawn per second while the mouse drags the
  view continuously (a move every 16 ms) for ``--seconds``;
* **style change**: from the click on a thumbnail to the first frame drawn of the new style (network,
  colour match, fast layer), median over styles not shown before, and over the same styles again
  (their albedo cached: the fast layer only);
* **slider move**: from a strength slider step (keyboard, a new strength each time) to the first
  frame drawn (kernels blended, network, colour match refitted, fast layer), median of several;
* **the look's first frame**: back at full strength, from a style click to the first frame of the
  look that *Render final output* fits (fitted in the background after the network's frame), in the
  server's clock (its ``fit`` message), with the fit's own time, for ``--looks`` styles.

Browser and server share this machine's cores, as a user's would. Rows: ``results/preview/bench.json``
and ``results/preview/bench.md`` (machine, load average before the run); ``screenshot.jpg``, README's.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]  # fmt: skip
STYLES = (
    "hokusai_great_wave.jpg",
    "van_gogh_starry_night.jpg",
    "texture_onyx_banded.jpg",
    "munch_the_scream.jpg",
    "signac_la_calanque.jpg",
    "photo_nasa_carina_pillar.jpg",
)


def cpu_model() -> str:
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor()


def latency(page, act) -> float:
    """Milliseconds from ``act`` (done inside the page, timestamped there) to the next fast frame drawn."""
    before = page.evaluate("window.mistyle.lastFast.at")
    started = act()
    page.wait_for_function(f"window.mistyle.lastFast.at > {before}", timeout=60_000)
    page.wait_for_timeout(800)  # let the path tracer start, so the next action interrupts it as a user's would
    return page.evaluate(f"window.mistyle.firstFastAfter({started})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--res", type=int, default=256)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--looks", type=int, default=2, help="styles whose look is fitted and timed")
    parser.add_argument(
        "--render-options",
        default="",
        help='mistyle-preview\'s --render-options ("--refine 0": a page that fits no look)',
    )
    parser.add_argument("--stem", default="bench", help="the results' file names: STEM.json, STEM.md")
    parser.add_argument("--out", type=Path, default=ROOT / "results" / "preview")
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    args = parser.parse_args()

    from playwright.sync_api import sync_playwright

    from mistyle.preview import page_settings
    from mistyle.preview import parser as preview_parser

    preview_args = ["--density", str(ROOT / "examples" / "smoke_64.vol"), "--render-options", args.render_options]
    style = ROOT / "mistyle" / "data" / "heldout_styles" / STYLES[0]
    fits_look = page_settings(preview_parser().parse_args(preview_args), style)[0].fits_look
    load_before = os.getloadavg()
    folder = Path(tempfile.mkdtemp(prefix="mistyle-bench-preview-"))
    for name in STYLES:
        shutil.copy(ROOT / "mistyle" / "data" / "heldout_styles" / name, folder / name)
    server = subprocess.Popen(
        [sys.executable, "-m", "mistyle.preview", "--density", str(ROOT / "examples" / "smoke_64.vol"),
         "--styles", str(folder), "--port", "0", "--res", str(args.res), "--out", str(folder / "out"),
         "--render-options", args.render_options],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    url = re.search(r"http://[\d.]+:\d+/", server.stdout.readline()).group(0)
    try:
        with sync_playwright() as driver:
            browser = driver.chromium.launch(executable_path=args.chromium, args=CHROMIUM_ARGS)
            page = browser.new_page(viewport={"width": 1100, "height": 900})
            page.goto(url)
            page.wait_for_function("window.mistyle.lastFast !== undefined", timeout=120_000)
            # Every fast frame's time, to find the first one after an action.
            page.evaluate(
                """() => {
                  const times = [];
                  const stats = window.mistyle.stats;
                  let seen = stats.fast;
                  const record = () => {
                    if (stats.fast !== seen) { seen = stats.fast; times.push(window.mistyle.lastFast.at); }
                    requestAnimationFrame(record);
                  };
                  requestAnimationFrame(record);
                  window.mistyle.fastTimes = times;
                  window.mistyle.firstFastAfter = (t) => times.find((at) => at > t) - t;
                }"""
            )
            box = page.locator("canvas").bounding_box()
            x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
            page.mouse.move(x, y)
            page.mouse.down()
            fast_before = page.evaluate("window.mistyle.stats.fast")
            started = page.evaluate("performance.now()")
            step, deadline = 0, time.monotonic() + args.seconds
            while time.monotonic() < deadline:
                step += 1
                page.mouse.move(x + 120 * math.sin(step / 20), y + 30 * math.sin(step / 33))
                page.wait_for_timeout(16)
            ended = page.evaluate("performance.now()")
            fast_after = page.evaluate("window.mistyle.stats.fast")
            page.mouse.up()
            orbit_fps = (fast_after - fast_before) / ((ended - started) / 1000)
            page.wait_for_timeout(1500)

            def click(index):
                return latency(
                    page,
                    lambda: page.evaluate(
                        f"() => {{ const t = performance.now(); document.querySelectorAll('#styles img')[{index}].click(); return t; }}"  # noqa: E501
                    ),
                )

            # Each style once (the network and the colour match run), then again (both cached).
            style_ms = [click(index) for index in range(1, min(len(STYLES), args.repeats + 1))]
            revisit_ms = [click(index) for index in range(1, min(len(STYLES), args.repeats + 1))]
            slider_ms = []
            page.locator("#strength").focus()
            for _ in range(args.repeats):  # a new strength each step: kernels, network and colour match again

                def press():
                    started = page.evaluate("performance.now()")
                    page.keyboard.press("ArrowLeft")
                    return started

                slider_ms.append(latency(page, press))
            # Back at full strength, each style's look: from the click to the look's first frame (the
            # server's clock), and the fit's own time, with no other change meanwhile.
            page.keyboard.press("End")
            look_first_ms, look_fit_s = [], []
            for index in range(args.looks if fits_look else 0):
                shown = page.evaluate("window.mistyle.stats.looksShown")
                page.locator("#styles img").nth(index).click()
                page.wait_for_function(f"window.mistyle.stats.looksShown > {shown}", timeout=300_000)
                fit = page.evaluate("window.mistyle.fit")
                look_first_ms.append(fit["first_look_ms"])
                look_fit_s.append(fit["seconds"])
            layer_ms = float(re.search(r"layer ([\d.]+) ms", page.locator("#info").inner_text()).group(1))
            page.wait_for_function("window.mistyle.stats.pathTraced > 0", timeout=60_000)
            page.wait_for_timeout(4000)  # a few path-traced passes: README's screenshot
            args.out.mkdir(parents=True, exist_ok=True)
            if args.stem == "bench":
                page.screenshot(path=args.out / "screenshot.jpg", type="jpeg", quality=88)
            browser.close()
    finally:
        server.terminate()
        server.wait(timeout=30)
        shutil.rmtree(folder, ignore_errors=True)
    result = {
        "res": args.res,
        "orbit_fps": orbit_fps,
        "orbit_seconds": args.seconds,
        "style_change_ms": statistics.median(style_ms),
        "style_change_ms_all": style_ms,
        "style_revisit_ms": statistics.median(revisit_ms),
        "style_revisit_ms_all": revisit_ms,
        "slider_move_ms": statistics.median(slider_ms),
        "slider_move_ms_all": slider_ms,
        "render_options": args.render_options,
        "look_first_frame_ms": statistics.median(look_first_ms) if look_first_ms else None,
        "look_first_frame_ms_all": look_first_ms,
        "look_fit_seconds_all": look_fit_s,
        "last_layer_ms": layer_ms,
        "machine": f"{cpu_model()}, {os.cpu_count()} cores",
        "load_average_before": [round(v, 2) for v in load_before],
        "command": "python experiments/bench_preview.py " + " ".join(sys.argv[1:]),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{args.stem}.json").write_text(json.dumps(result, indent=1) + "\n")
    looks = (
        f"| style change to the look's first frame, full strength (median of {len(look_first_ms)}; the fits "
        f"took {', '.join(f'{v:.1f}' for v in look_fit_s)} s) | {result['look_first_frame_ms']:.0f} ms |\n"
        if look_first_ms
        else ""
    )
    (args.out / f"{args.stem}.md").write_text(
        "| measure | value |\n|---|---|\n"
        f"| frames drawn per second while orbiting ({args.res}^2, {args.seconds:g} s) | {orbit_fps:.1f} |\n"
        f"| style change to first frame, a style not shown before (median of {len(style_ms)}) | "
        f"{result['style_change_ms']:.0f} ms |\n"
        f"| style change to first frame, a style shown before (median of {len(revisit_ms)}) | "
        f"{result['style_revisit_ms']:.0f} ms |\n"
        f"| strength slider step to first frame (median of {args.repeats}) | {result['slider_move_ms']:.0f} ms |\n"
        + looks
        + f"| fast layer, last frame | {layer_ms:.0f} ms |\n\n"
        f"Machine: {result['machine']}; load average before the run {result['load_average_before']}. "
        f"Browser (headless Chromium) and server on the same cores. `{result['command'].strip()}`.\n"
    )
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
