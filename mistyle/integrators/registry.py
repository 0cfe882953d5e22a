"""Registering mistyle's Mitsuba plugins for the active variant (``register``).

Plugins are defined against the active Mitsuba variant, so they are registered when a scene needs them
(``layer_scene``, the path tracer) rather than at import of ``mistyle``; after a variant change they are
defined again.
"""

from __future__ import annotations

import importlib

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
