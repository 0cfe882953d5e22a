"""Conventions written once: every module that needs one of these values imports it from here.

Numbers (each chosen by measurement where a comment says so):

* ``DEFAULT_DENSITY_SCALE``: extinction per unit density, ``sigma_t = scale * density``, in
  1/world-length with the medium box's longest side 1. Training data and renders use it unless
  told otherwise.
* ``DEFAULT_ENV_RADIANCE``: the training light, a constant white environment. Single scattering
  under a unit environment cannot exceed a radiance of about 0.7 even for white albedo, which the
  tone curve shows as mid grey, so bright styles were out of reach. Le = 8 gave the lowest held-out
  SWD of 2, 4, 8 and 16 with ``experiments/optimize_albedo.py --quick`` and puts white albedo near the
  top of the display range.
* ``ORBIT_DISTANCE``: radius of the camera orbit (``mistyle.scenes.CameraPath``) by default: the orbit
  every shipped config trains on and the bundled networks record, so an image framed by default is framed
  as ``mistyle-render`` frames it.
* ``LAYER_MARCH_STEPS``: segments of the fast layer's march along a camera ray, the shipped configs'.
* ``MAX_FIT_STEPS``: the most gradient steps a fit (look, refinement, solid texture) may be asked for.
* ``IMAGE_SIDES``: the smallest and largest side of a rendered image, in pixels.
* ``HELD_OUT_VIEW``: the orbit position of the first view that evaluations, reports and final
  renders use. Training samples positions uniformly, so no position is strictly unseen; this one
  sits between the four quarter turns that previews and tests favour.
* ``FOREGROUND_THRESHOLD``: a pixel sees the medium when any channel of its linear radiance
  exceeds this (masks of the losses, the metrics and the colour match's renders).
* ``LS_DIRECTIONS``: K, the Hammersley directions of the in-scattered radiance precompute.

Names of choices (config values and command-line options), so no string literal is repeated.
"""

from __future__ import annotations

DEFAULT_DENSITY_SCALE = 20.0
DEFAULT_ENV_RADIANCE = 8.0
ORBIT_DISTANCE = 1.7
LAYER_MARCH_STEPS = 48
MAX_FIT_STEPS = 10000
IMAGE_SIDES = (8, 8192)
MIN_CAMERA_DISTANCE = 0.9  # cameras stay outside the medium box (half-diagonal of the unit cube: 0.87)
MAX_DENSITY = 1e6  # above this, float32 statistics of the network (DAIN variances) overflow
MAX_DENSITY_SCALE = 1e6  # extinction per unit density; beyond it a voxel is opaque many times over
MAX_EXTINCTION = 1e4
"""Largest extinction (max density x density scale, per unit of the box's longest side) mistyle renders.
Mitsuba's volpath crosses a medium in free flights against its majorant, so a path's steps, and a render's
time, grow in proportion to it: the colour match of a 16^3 blob takes 2 s at 20 (training's) and 65 s at
1e4 on two CPU cores, and would take over a day at the 1.7e7 of density 8.4e5 at scale 20. At 1e4 the mean free
path is a ten-thousandth of the box (a voxel of a 1024^3 grid is ten free paths deep): denser looks the same."""
MAX_GRID_VOXELS = 2**30
"""Largest grid mistyle reads into memory (4 GiB as float32); file readers refuse larger declared sizes
before allocating (``mistyle.files``; ``vdb_convert.MAX_DENSE_VOXELS`` is the same bound)."""
HELD_OUT_VIEW = 0.0625
REFINE_LAYER_STEPS, REFINE_PATH_STEPS = 120, 16  # fit.RefineSettings' steps (here: --help needs no torch)
FOREGROUND_THRESHOLD = 1e-3
LS_DIRECTIONS = 128

LAYER_SCHEMES = ("exact", "midpoint", "riemann")
"""Per-segment weights of the fast layer (see ``mistyle.integrators.single_scatter``)."""
DEFAULT_LAYER_SCHEME = "exact"

EXTRACTOR_KINDS = ("auto", "vgg16", "vgg16-random", "filterbank")
"""Feature extractors a config or a command line may ask for (``mistyle.model.features``)."""
OFFLINE_EXTRACTOR = "filterbank"
"""What ``auto`` falls back to when no VGG16 ImageNet weights are found."""

STYLE_LOSSES = ("histogram", "gram", "meanstd")
"""Losses on the extractor's feature levels (the paper's objective and its ablations)."""
OBJECTIVES = ("features", "sliced")
"""``features``: tone map -> extractor -> ``STYLE_LOSSES`` per level; ``sliced``: RGB and pixel-patch sliced
Wasserstein (``objective.style.SlicedObjective``, the fidelity study's choice)."""
LOSS_MASKS = ("foreground", "body")
"""Which pixels the style term compares: any that sees the medium, or the medium's body."""
LIGHT_KINDS = ("constant", "envmap", "point", "area")
UP_AXES = ("y", "z")
"""World up axes of the scenes mistyle's files go to: ``y`` (mistyle, Mitsuba, Houdini), ``z`` (Blender)."""
DEVICES = ("cpu", "cuda")
TEMPORAL_GRADIENTS = ("both", "current")
"""Which frames the temporal term's gradient reaches: t and t+1, or t only (frame t+1 as a fixed target,
which spares the network's backward pass for it)."""
COLOUR_MATCH_GRADIENTS = ("map", "fit")
"""How training's colour match passes the gradient: through the fitted map only, or through the fit too
(``colour_match.fit_colour_match_torch``)."""
PRECISIONS = ("fp32", "bf16")
"""The network's training precision: float32, or bfloat16 autocast (``run.precision``)."""
STYLE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".webp", ".bmp", ".gif", ".exr")
"""The picture files a style may be: ``io.load_style`` reads them; a ``--style`` folder stands for these files."""
