"""The fast layer's Mitsuba side: the ``mistyle_single_scatter`` plugin, the Ls precompute
(``inscatter``), the prepared density and the layer's scene. Nothing torch-specific: the torch side
is ``mistyle.bridge_torch``.

Plugins are defined against the active Mitsuba variant, so they are registered by ``register()``
(which ``layer_scene`` calls) rather than at import of ``mistyle``.
"""

from __future__ import annotations

import importlib

from .layer import layer_scene
from .prepared import PreparedDensity, prepare_density

__all__ = ["PreparedDensity", "layer_scene", "prepare_density", "register"]

_registered_variant: str | None = None


def register() -> None:
    """Register mistyle's integrators for the active Mitsuba variant; cheap when already done."""
    global _registered_variant
    import mitsuba as mi

    if _registered_variant == mi.variant():
        return
    from . import single_scatter

    if _registered_variant is not None:
        importlib.reload(single_scatter)
    _registered_variant = mi.variant()
