"""How a look is fitted (``LookSettings``) and which frames it is fitted on."""

from __future__ import annotations

from dataclasses import dataclass

from ..conventions import LAYER_MARCH_STEPS, MAX_FIT_STEPS

COLOUR_MATCH_MODES = ("through", "after", "none")
LR_SCHEDULES = ("constant", "cosine")
VIEW_SAMPLINGS = ("independent", "stratified")
TEXTURE_STARTS = ("zeros", "solid")


@dataclass
class LookSettings:
    """How a look is fitted (``fit_look``); the defaults are ``mistyle-render --save-look``'s."""

    steps: int = 90
    lr: float = 0.02
    views_per_step: int = 3
    layer_res: int = 64
    layer_steps_per_ray: int = LAYER_MARCH_STEPS
    tune_sites: tuple = (3,)  # the kernel sites tuned (SKPN.sites; (3,), the head only, reuses the decoder's body)
    tune_decoder: tuple = (2,)  # indices of SKPN.decoder's convolutions tuned with the kernels
    rgb_weight: float = 1.0
    patch_weight: float = 0.05
    tv_weight: float = 10.0
    # The objective's gradient term (SlicedObjective.structure_weight): the style's strokes, their sizes
    # and orientations. Chosen on 28 validation pairs (experiments/look_structure_study.py): 0 until then.
    structure_weight: float = 0.03
    colour_match: str = (
        "after"  # "after": fitted on the tuned network's albedo; "through": first, fitted through; "none"
    )
    noise_channels: int = 0  # smooth noise fields (look_noise) the head adds, weighted, before its tanh
    texture_side: int = 64  # > 0: a texture of this many texels along the box's longest side, added before the tanh
    texture_lr: float = 0.05
    texture_init: float = 0.0  # spread of the texture's random start (0: zeros); colour variation to spread
    # "solid": the texture starts as a solid texture of the style (mistyle.solid_texture), centred and
    # scaled by texture_start_strength in the head's logits; "zeros": from texture_init's noise. Chosen on
    # the validation pairs (docs/decisions/2026-12-05-solid-texture.md): a 32-texel texture from zeros
    # until then.
    texture_start: str = "solid"
    texture_start_strength: float = 4.0
    lr_schedule: str = "constant"  # or "cosine": every learning rate decays to zero over the steps
    # "stratified": a step's views evenly spaced from a random offset (CameraPath.sample_stratified), or
    # "independent" (the default until 2026-12-03): stratified scored better on the held-out pairs in
    # RGB, patch and structure (docs/decisions/2026-12-03-look-fit-speed.md).
    view_sampling: str = "stratified"
    # Steps before ``steps`` on the key frames at 1/coarse_factor of their resolution (``coarse_frame``):
    # the head's convolution, the layer's renders and the objective each cost several times less there.
    coarse_steps: int = 0
    coarse_factor: int = 2
    # > 0: the sliced objective draws each step's directions from this many, along which the style's
    # projections are sorted once (objective.losses.ProjectedTarget); 0: fresh directions every step.
    direction_pool: int = 0
    seed: int = 0

    def __post_init__(self):
        if not 0 <= self.steps <= MAX_FIT_STEPS:
            raise ValueError(f"A look's fit steps must lie in [0, {MAX_FIT_STEPS}], got {self.steps}.")
        if not 0 <= self.direction_pool <= 65536:
            raise ValueError(f"direction_pool must lie in [0, 65536], got {self.direction_pool}.")
        if not 0 <= self.coarse_steps <= MAX_FIT_STEPS:
            raise ValueError(f"A look's coarse steps must lie in [0, {MAX_FIT_STEPS}], got {self.coarse_steps}.")
        if self.coarse_factor not in (2, 4):
            raise ValueError(f"coarse_factor must be 2 or 4, got {self.coarse_factor}.")
        if not set(self.tune_decoder) <= {0, 1, 2}:
            raise ValueError(f"tune_decoder takes decoder convolutions 0, 1, 2; got {self.tune_decoder}.")
        if self.view_sampling not in VIEW_SAMPLINGS:
            raise ValueError(f"view_sampling must be one of {', '.join(VIEW_SAMPLINGS)}, got {self.view_sampling!r}.")
        if self.lr_schedule not in LR_SCHEDULES:
            raise ValueError(f"lr_schedule must be one of {', '.join(LR_SCHEDULES)}, got {self.lr_schedule!r}.")
        if self.texture_start not in TEXTURE_STARTS:
            raise ValueError(f"texture_start must be one of {', '.join(TEXTURE_STARTS)}, got {self.texture_start!r}.")
        if not 0.0 <= self.texture_start_strength <= 20.0:
            raise ValueError(f"texture_start_strength must lie in [0, 20], got {self.texture_start_strength}.")
        if self.colour_match not in COLOUR_MATCH_MODES:
            raise ValueError(f"colour_match must be one of {', '.join(COLOUR_MATCH_MODES)}, got {self.colour_match!r}.")
        if not set(self.tune_sites) <= {0, 1, 2, 3}:
            raise ValueError(f"tune_sites takes kernel sites 0-3; got {self.tune_sites}.")
        if not (self.tune_sites or self.tune_decoder or self.texture_side or self.noise_channels):
            raise ValueError("A look must fit something: kernel sites, decoder convolutions, a texture or noise.")
        self.tune_decoder = tuple(sorted(set(int(i) for i in self.tune_decoder)))
        self.tune_sites = tuple(sorted(set(int(i) for i in self.tune_sites)))

    @property
    def fixed_stage(self) -> str | None:
        """How far into the decoder nothing is tuned, so that each key frame's values up to there are
        computed once: ``"logits"`` (no part of the network: only a texture or noise weights), ``"site"``
        (the last convolution only: the last kernel site's output), ``"body"`` (the head only: the
        decoder's body), or None."""
        if not self.tune_sites and not self.tune_decoder:
            return "logits"
        if not self.tune_sites and set(self.tune_decoder) <= {2}:
            return "site"
        if set(self.tune_sites) <= {3} and set(self.tune_decoder) <= {2}:
            return "body"
        return None


def default_key_frames(count: int) -> list[int]:
    """The frames a look is fitted on by default: the first, middle and last of ``count`` frames."""
    if count < 1:
        raise ValueError("A look needs at least one frame to fit on.")
    return sorted({0, (count - 1) // 2, count - 1})


def parse_key_frames(text: str, count: int) -> list[int]:
    """``--key-frames``: comma-separated 0-based frame indices (``"0,40,80"``), checked against ``count``."""
    try:
        frames = sorted({int(part) for part in text.split(",") if part.strip()})
    except ValueError:
        raise ValueError(f"--key-frames takes comma-separated frame indices such as 0,40,80; got {text!r}.") from None
    if not frames:
        raise ValueError(f"--key-frames names no frame: {text!r}.")
    outside = [f for f in frames if not 0 <= f < count]
    if outside:
        raise ValueError(
            f"--key-frames {', '.join(map(str, outside))} lie outside the sequence's frames 0-{count - 1}."
        )
    return frames
