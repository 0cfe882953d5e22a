"""What "looks like the style" means: masks, style losses, the training objective and the metrics.

``losses`` holds the paper's losses, ``masks`` the foreground masks, ``style.StyleObjective`` the one
"tone-map -> mask -> extractor -> style loss" used by training, direct fitting and refinement, and
``metrics`` the distances reported by experiments and ``render_final``. Imports ``mistyle.display``
and ``mistyle.warp``; imported by ``fit``, ``train`` and the inference path.
"""
