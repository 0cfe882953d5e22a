"""The fast layer as Mitsuba plugins, and the in-scattered radiance precompute.

Plugins are defined against the active Mitsuba variant, so they are registered by ``register()``
(which ``mistyle.backend.use_variant`` calls) rather than at import of ``mistyle``.
"""

from __future__ import annotations

import importlib

SCHEMES = ("exact", "midpoint", "riemann")
"""Per-segment weights of the fast layer; see ``single_scatter``."""
DEFAULT_SCHEME = "exact"

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
