"""mistyle: volumetric appearance stylization with a differentiable Mitsuba 3 rendering layer.

``mistyle.stylize(density, style_image) -> albedo``, ``mistyle.render(density, albedo, view=u) ->
image``, ``mistyle.display(image)`` (the PNGs' tone curve) and ``mistyle.load_density(path)`` (see
``mistyle.api``), ``mistyle.fit_look`` and ``mistyle.Look`` (``mistyle.look``: a style fitted once on
key frames, applied to every frame), and ``mistyle.Pipeline`` / ``mistyle.PipelineSettings``
(``mistyle.pipeline``: every setting and every stage's result); they load torch and Mitsuba on first
use, so ``import mistyle`` stays light.
"""

__version__ = "0.1.0"

_PUBLIC = ("stylize", "render", "display", "load_density", "fit_look", "Look", "Pipeline", "PipelineSettings")


def __getattr__(name):
    if name in _PUBLIC:
        from . import api as module

        return getattr(module, name)
    raise AttributeError(f"module 'mistyle' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + list(_PUBLIC))
