"""Training SKPN: config files, datasets, the training loop and ``python -m mistyle.train``.

Imports ``model``, ``objective``, ``fit``, ``data`` and the layer; nothing imports it, so inference
(``mistyle.api``, ``render_final``) runs without it.
"""
