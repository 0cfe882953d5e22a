"""mistyle: volumetric appearance stylization with a differentiable Mitsuba 3 rendering layer."""

__version__ = "0.1.0"
