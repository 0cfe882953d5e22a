"""The product: density + style -> network -> colour match -> look or refinement -> path tracing, in memory.

``settings``: what decides the output (``PipelineSettings``, ``RenderSettings``); ``frames``: what a
pipeline works on and returns (``Frames``, ``Stylization``); ``chain``: the ``Pipeline`` itself.
"""

from .chain import Pipeline
from .frames import Frames, Stylization, flicker_report
from .settings import PipelineSettings, RenderSettings, default_refinement

__all__ = [
    "Frames",
    "Pipeline",
    "PipelineSettings",
    "RenderSettings",
    "Stylization",
    "default_refinement",
    "flicker_report",
]
