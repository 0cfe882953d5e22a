"""What studies built on the benchmark share: its metric renders' options and scoring, in one spelling.

A study (``experiments/``) scores its arms exactly as ``mistyle-bench`` scores methods:
``runner.score`` from ``runner.metric_views``, next to ``methods.uniform_baseline``. Scripts here import it
as ``from study import ...`` (Python puts a script's own folder first on its path).
"""

from __future__ import annotations

from mistyle.benchmark.methods import uniform_baseline
from mistyle.benchmark.runner import METRIC_VIEWS, metric_views, score

__all__ = ["METRIC_VIEWS", "add_metric_arguments", "metric_views", "score", "uniform_baseline"]


def add_metric_arguments(parser, res: int = 128, spp: int = 16) -> None:
    """``--res`` and ``--spp`` of the metric renders and ``--cache`` of the held-out densities."""
    parser.add_argument("--res", type=int, default=res, help="metric renders' side")
    parser.add_argument("--spp", type=int, default=spp, help="metric renders' paths per pixel")
    parser.add_argument("--cache", default="data/heldout", help="where held-out densities are cached")
