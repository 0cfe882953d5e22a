"""What "looks like the style" means: masks, style losses, the training objective and the metrics.

``losses`` holds the paper's losses and the sliced-Wasserstein loss, ``masks`` the foreground and
body masks, ``style`` the objectives (``StyleObjective``: the paper's "tone-map -> mask -> extractor
-> style loss"; ``SlicedObjective``: RGB and pixel-patch sliced Wasserstein, used by refinement and
selectable for training), and ``metrics`` the distances reported by experiments and ``render_final``
(``style_fidelity``: the fidelity benchmark's). Imports ``mistyle.tone``
and ``mistyle.warp``; imported by ``fit``, ``train`` and the inference path.
"""
