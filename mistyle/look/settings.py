"""How a look is fitted (``LookSettings``) and which frames it is fitted on."""

from __future__ import annotations

from dataclasses import dataclass

from ..conventions import LAYER_MARCH_STEPS, MAX_FIT_STEPS


@dataclass
class LookSettings:
    """How a look is fitted (``fit_look``); the defaults are ``mistyle-render --save-look``'s.

    Only what the product's fit uses: study arms that lost (a colour match fitted through the steps or none,
    noise fields, a texture from noise, a cosine schedule, views drawn independently, coarse steps, a pool
    of directions) were removed on 2026-12-05 with the decisions that record them; their studies ran at the
    commits their results folders name."""

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
    texture_side: int = 64  # > 0: a texture of this many texels along the box's longest side, added before the tanh
    texture_lr: float = 0.05
    # The texture starts as a solid texture of the style (mistyle.solid_texture), centred and scaled by
    # this in the head's logits (0: from zeros, the look until 2026-12-05). Chosen on the validation pairs
    # (docs/decisions/2026-12-05-solid-texture.md).
    texture_start_strength: float = 4.0
    seed: int = 0

    def __post_init__(self):
        if not 0 <= self.steps <= MAX_FIT_STEPS:
            raise ValueError(f"A look's fit steps must lie in [0, {MAX_FIT_STEPS}], got {self.steps}.")
        if not set(self.tune_decoder) <= {0, 1, 2}:
            raise ValueError(f"tune_decoder takes decoder convolutions 0, 1, 2; got {self.tune_decoder}.")
        if not 0.0 <= self.texture_start_strength <= 20.0:
            raise ValueError(f"texture_start_strength must lie in [0, 20], got {self.texture_start_strength}.")
        if not set(self.tune_sites) <= {0, 1, 2, 3}:
            raise ValueError(f"tune_sites takes kernel sites 0-3; got {self.tune_sites}.")
        if not (self.tune_sites or self.tune_decoder or self.texture_side):
            raise ValueError("A look must fit something: kernel sites, decoder convolutions or a texture.")
        self.tune_decoder = tuple(sorted(set(int(i) for i in self.tune_decoder)))
        self.tune_sites = tuple(sorted(set(int(i) for i in self.tune_sites)))

    @property
    def fixed_stage(self) -> str | None:
        """How far into the decoder nothing is tuned, so that each key frame's values up to there are
        computed once: ``"logits"`` (no part of the network: only a texture), ``"site"``
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
