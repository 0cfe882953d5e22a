"""What studies built on the benchmark share: its metric renders' options and scoring, in one spelling.

A study (``experiments/``) scores its arms exactly as ``mistyle-bench`` scores methods:
``runner.score`` from ``runner.metric_views``, next to ``methods.uniform_baseline``. Scripts here import it
as ``from study import ...`` (Python puts a script's own folder first on its path).
"""

from __future__ import annotations

from mistyle.benchmark.methods import uniform_baseline
from mistyle.benchmark.runner import METRIC_VIEWS, metric_views, score

__all__ = [
    "METRIC_VIEWS",
    "USER_SCORING",
    "add_metric_arguments",
    "arm_study",
    "contact_sheet",
    "metric_views",
    "score",
    "score_as_users_see",
    "uniform_baseline",
]

USER_SCORING = dict(res=256, spp=64, denoise="oidn")
"""How ``mistyle-render`` shows its output, and so how a study scores it."""


def score_as_users_see(context, density, albedo, style, seed: int = 0):
    """``runner.score`` of ``albedo`` with ``context``'s (``methods.Context``) views, density scale and
    light, at ``USER_SCORING``: ``(metrics, images)``."""
    return score(
        density,
        albedo,
        style,
        context.views,
        density_scale=context.density_scale,
        radiance=context.radiance,
        seed=seed,
        **USER_SCORING,
    )


def contact_sheet(
    lines: list, columns: list[str], path, tile: int, captions: list[str] | None = None, quality: int = 85
) -> None:
    """A JPEG of one line of tiles per entry of ``lines``, ``(style image path, [tile PNG paths])``: the style
    squared, then each tile resized to ``tile`` (grey where a tile is missing); ``columns`` name the tiles
    above them, ``captions`` (one per line) sit in each line's lower left corner."""
    import numpy as np
    from PIL import Image, ImageDraw

    from mistyle.files import load_style
    from mistyle.model.features import square_style

    canvas = np.full((len(lines) * tile + 16, len(columns) * tile, 3), 1.0, np.float32)
    for index, (style_path, tiles) in enumerate(lines):
        cells = [square_style(load_style(style_path), tile).permute(1, 2, 0).numpy()]
        for tile_path in tiles:
            cells.append(
                np.asarray(Image.open(tile_path).convert("RGB").resize((tile, tile), Image.LANCZOS), np.float32) / 255
                if tile_path.exists()
                else np.full((tile, tile, 3), 0.5, np.float32)
            )
        canvas[16 + index * tile : 16 + (index + 1) * tile] = np.concatenate(cells, axis=1)
    image = Image.fromarray((canvas * 255 + 0.5).astype(np.uint8))
    draw = ImageDraw.Draw(image)
    for column, name in enumerate(columns):
        draw.text((column * tile + 4, 2), name, fill="black")
    for index, caption in enumerate(captions or []):
        draw.text((4, 16 + (index + 1) * tile - 14), caption, fill="white")
    image.save(path, quality=quality)


def add_metric_arguments(parser, res: int = 128, spp: int = 16) -> None:
    """``--res`` and ``--spp`` of the metric renders and ``--cache`` of the held-out densities."""
    parser.add_argument("--res", type=int, default=res, help="metric renders' side")
    parser.add_argument("--spp", type=int, default=spp, help="metric renders' paths per pixel")
    parser.add_argument("--cache", default="data/heldout", help="where held-out densities are cached")


def arm_study(description: str, out, register_arms, validation_pairs, argv=None, baselines=()) -> None:
    """The command line of a study of look arms scored as users see them (256^2, 64 spp, OIDN): the
    default output, the ``baselines`` (benchmark methods) and the arms (``register_arms()``: their names,
    registered as benchmark methods) on ``validation_pairs()``; ``--heldout ARM``: one arm on the
    held-out split, into ``out/heldout``; ``--report-only``: the report of ``out``'s rows."""
    import argparse
    from pathlib import Path

    from mistyle.benchmark.runner import report, run
    from mistyle.benchmark.splits import split_pairs

    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--report-only", action="store_true")
    parser.add_argument("--heldout", default="", help="an arm to score on the held-out split (out/heldout)")
    args = parser.parse_args(argv)
    out, arms = Path(out), register_arms()
    scoring = dict(USER_SCORING, resume=True)
    if args.report_only:
        report(out)
    elif args.heldout:
        run(out / "heldout", split_pairs("heldout"), [args.heldout], split="heldout", **scoring)
    else:
        run(out, validation_pairs(), ["default", *baselines] + arms, split="validation", **scoring)


def require_frozen_commit(script: str, commit: str) -> None:
    """Stop a frozen study run on a later commit (whose settings no longer have its arms), naming the
    checkout it runs from."""
    import subprocess
    from pathlib import Path

    here = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    if here and not here.startswith(commit) and not commit.startswith(here):
        name = Path(script).name
        raise SystemExit(
            f"{name} is a frozen study: it ran at commit {commit}, whose LookSettings has its arms. Run it there: "
            f"git worktree add ../frozen-{commit} {commit} && cd ../frozen-{commit} && python experiments/{name} ..."
        )
