"""Looks: a style fitted once on a few key frames, then applied feed-forward to every frame.

    from mistyle.look import fit_look, Look

    look = fit_look(stylizer, frames, "wave.png")       # a stylizer.Stylizer; the first, middle, last frame
    look.save("wave.look")
    look = Look.load("wave.look")                        # the bundled network, or checkpoint=...
    albedo = look.stylize(density)                       # (Z, Y, X, 3): any frame, about 1 s at 64^3

``Pipeline.fit_look`` and ``mistyle.fit_look`` fit with a pipeline's settings; ``mistyle-render
--save-look``/``--look`` adapt them (``docs/looks.md``).

What a look holds (``LOOK_VERSION`` 1), chosen by measurement (``experiments/look_study.py``,
``results/look_study/``, ``docs/decisions/2026-12-02-looks.md``):

* **The network's head, fine-tuned at test time.** The last kernel site's stylizing kernel starts
  from the SKPN's prediction for the style and is fitted with the last decoder convolution
  (``LookSettings.tune_sites``, ``tune_decoder``) through the fast layer against the sliced objective
  (RGB and patch sliced Wasserstein, the refinement's) on the key frames' renders. The encoder and
  the decoder's body are the checkpoint's, computed once per key frame, which is what makes the fit
  cheap; with them fixed, the site (a channel mix and DAIN) folds into the last convolution, so a step
  runs one convolution (``SKPN.folded_head_logits``). The look names the checkpoint by its SHA-256.
* **A texture over the medium's box** (``texture_side`` texels along the longest side), added before
  the head's tanh: strokes and grain where the density alone has no structure. It starts as a solid
  texture of the style (``mistyle.solid_texture``: every slice has the style's patches), scaled in the
  head's logits. It lies over the box; in a sequence with velocities it travels with them
  (``mistyle.advection``).
* **The colour match's map** (``colour_match.ColourMatch``), fitted after the fit on the albedo of the
  first key frame the layer sees: a function of colour, shared by every frame like a sequence's.
* The style's thumbnail (``THUMBNAIL_SIDE`` pixels), the density scale, the orbit and the fit's
  settings, so that a render from the look is measured against its style and lit as it was fitted.

Applied to a frame, the look runs the network on that frame's own density with the fitted head and
texture (``prepare_frame``, ``frame_albedo``: the fit's own functions), then the colour match; no
frame is refined and each frame depends on nothing but the look, its density and, where the texture
follows a sequence's velocities, those of the few frames before it (``advection.first_needed``).
"""

from ..fit import DIVERGENCE_WINDOW, diverged
from .fit import fit_look
from .fitted import (
    DENSITY_SCALE_TOLERANCE,
    LOOK_FORMAT,
    LOOK_VERSION,
    MAX_LOOK_VALUE,
    PAYLOAD_DIGEST_KEY,
    SIZE_RATIO_NOTE,
    Look,
    check_look_record,
    checkpoint_digest,
    is_look_file,
    payload_digest,
)
from .frames import (
    THUMBNAIL_SIDE,
    advected_texture,
    cropped_fit,
    frame_albedo,
    frame_key,
    prepare_frame,
    solid_texture_start,
    stretch_texture,
    thumbnail_of,
)
from .settings import (
    LookSettings,
    default_key_frames,
    parse_key_frames,
)

__all__ = [
    "DENSITY_SCALE_TOLERANCE",
    "DIVERGENCE_WINDOW",
    "LOOK_FORMAT",
    "LOOK_VERSION",
    "MAX_LOOK_VALUE",
    "PAYLOAD_DIGEST_KEY",
    "SIZE_RATIO_NOTE",
    "THUMBNAIL_SIDE",
    "Look",
    "LookSettings",
    "advected_texture",
    "check_look_record",
    "checkpoint_digest",
    "cropped_fit",
    "default_key_frames",
    "diverged",
    "fit_look",
    "frame_albedo",
    "frame_key",
    "is_look_file",
    "parse_key_frames",
    "payload_digest",
    "prepare_frame",
    "solid_texture_start",
    "stretch_texture",
    "thumbnail_of",
]
