"""mistyle: volumetric appearance stylization with a differentiable Mitsuba 3 rendering layer.

``mistyle.stylize(density, style_image) -> albedo`` and ``mistyle.render(density, albedo) -> image``
(see ``mistyle.api``); they load torch and Mitsuba on first use.
"""

__version__ = "0.1.0"


def __getattr__(name):
    if name in ("stylize", "render"):
        from . import api as module

        return getattr(module, name)
    raise AttributeError(f"module 'mistyle' has no attribute {name!r}")
