"""The fast layer's Mitsuba side: the ``mistyle_single_scatter`` plugin, the Ls precompute
(``inscatter``), the prepared density and the layer's scene. Nothing torch-specific: the torch side
is ``mistyle.bridge_torch``.

Plugins are defined against the active Mitsuba variant, so they are registered by ``register()``
(``registry``; ``layer_scene`` calls it) rather than at import of ``mistyle``.
"""

from __future__ import annotations

from .layer import layer_scene
from .prepared import PreparedDensity, prepare_density
from .registry import register

__all__ = ["PreparedDensity", "layer_scene", "prepare_density", "register"]
