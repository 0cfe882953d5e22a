"""The style-fidelity benchmark: one runner, one row schema, every method registered by name.

    mistyle-bench --quick                                  # a minute: one small held-out density, two styles
    mistyle-bench                                          # the held-out split: every method, every pair
    mistyle-bench --methods network,default --resume       # add rows; pairs already scored are skipped
    mistyle-bench --report-only                            # the table and the contact sheet from the rows

Protocol (``docs/benchmark.md`` is its reference page):

* **Pairs**: every (density, style) of a split (``splits``): the held-out densities and styles of
  ``mistyle.data.heldout``, which training never sees (split by source).
* **Methods** (``methods.METHODS``): the product (``default``: the pipeline at ``mistyle-render``'s
  defaults; ``network``: feed-forward, ``--refine 0``), the network without the colour match, the
  must-beat baselines (``uniform``: one colour matched to the style's mean; ``density_ramp``,
  ``smooth_noise``, ``tuned_noise`` and ``solid_texture``: training-free fields given the style's colours
  by the same colour match the product uses), and the upper reference (``optimised``: direct
  optimisation of the albedo grid).
* **Scoring**: each albedo path traced (``volpath``, multiple scattering, the training light) from
  ``METRIC_VIEWS`` views evenly around the orbit and scored with
  ``objective.metrics.style_fidelity`` (RGB SWD, patch SWD, hue coverage) against the style.
* **Rows** (``runner.Row``): one JSON line per (method, density, style) with the metrics, the seconds,
  the commit, the settings and the checkpoint's hash; the table gives medians per method and the
  medians of per-pair ratios to the uniform baseline and to the two noise baselines.
"""

from .methods import METHODS, Method
from .runner import METRIC_VIEWS, Row, run
from .splits import SPLITS, split_pairs

__all__ = ["METHODS", "METRIC_VIEWS", "Method", "Row", "SPLITS", "run", "split_pairs"]
