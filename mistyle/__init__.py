"""mistyle: volumetric appearance stylization with a differentiable Mitsuba 3 rendering layer.

``mistyle.stylize(density, style_image) -> albedo``, ``mistyle.render(density, albedo, view=u) ->
image``, ``mistyle.display(image)`` (the PNGs' tone curve) and ``mistyle.load_density(path)`` (see
``mistyle.api``), ``mistyle.fit_look``, ``mistyle.Look`` and ``mistyle.LookSettings`` (``mistyle.look``: a
style fitted once on key frames, applied to every frame), and ``mistyle.Pipeline`` /
``mistyle.PipelineSettings`` / ``mistyle.RenderSettings`` (``mistyle.pipeline``: every setting and every
stage's result); they load torch and Mitsuba on first use, so ``import mistyle`` stays light. Each checks
its arguments first and names the one that is wrong.
"""

from .version import __version__  # noqa: F401 - the package's version, as mistyle.__version__

# ``api.__all__``, named here so that ``import mistyle`` does not load torch and Mitsuba to learn it
# (tests/test_api_checks.py keeps the two equal).
_PUBLIC = (
    "stylize",
    "render",
    "display",
    "load_density",
    "load_style",
    "fit_look",
    "Look",
    "LookSettings",
    "Pipeline",
    "PipelineSettings",
    "RenderSettings",
    "Stylizer",
    "path_trace",
)


def __getattr__(name):
    if name in _PUBLIC:
        from . import api as module

        return getattr(module, name)
    raise AttributeError(f"module 'mistyle' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + list(_PUBLIC))
