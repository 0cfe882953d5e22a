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
  (``mistyle.advection``). Optionally (off by default) smooth-noise fields the
  head weighs.
* **The colour match's map** (``colour_match.ColourMatch``), fitted after the fit on the albedo of the
  first key frame the layer sees: a function of colour, shared by every frame like a sequence's.
* The style's thumbnail (``THUMBNAIL_SIDE`` pixels), the density scale, the orbit and the fit's
  settings, so that a render from the look is measured against its style and lit as it was fitted.

Applied to a frame, the look runs the network on that frame's own density with the fitted head and
texture (``prepare_frame``, ``frame_albedo``: the fit's own functions), then the colour match; no
frame is refined and each frame depends on nothing but the look, its density and, where the texture
follows a sequence's velocities, those of the few frames before it (``advection.first_needed``).
"""

from __future__ import annotations

import copy
import hashlib
import io
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .conventions import LAYER_MARCH_STEPS, MAX_FIT_STEPS

LOOK_FORMAT = "mistyle-look"
LOOK_VERSION = 1
THUMBNAIL_SIDE = 256
"""The longest side of the style picture a look keeps: what renders from it are measured against."""
SIZE_RATIO_NOTE = 2.0
"""A frame more than this many times larger or smaller (longest side) than the key frames gets a note."""
DENSITY_SCALE_TOLERANCE = 1e-6
COLOUR_MATCH_MODES = ("through", "after", "none")
PAYLOAD_DIGEST_KEY = "payload_sha256"
"""Where a saved look records ``payload_digest`` of its tensors and meta; ``Look.load`` checks it (looks saved
before it was recorded load without, checked for shape, finiteness and magnitude only)."""
MAX_LOOK_VALUE = 1e4
"""The largest magnitude a look's numbers may have. A fit moves the network's kernels and convolutions, the
texture and the colour tables by amounts of order one; a value beyond this is damage, and it would overflow
the network's float32 statistics (DAIN) into NaN albedos."""
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


def checkpoint_digest(path) -> str:
    """SHA-256 of a checkpoint file: which network a look was fitted with."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


@dataclass
class Look:
    """A fitted look (module docstring). ``network`` is the checkpoint's SKPN with the tuned decoder
    layers; ``stylizer`` the loaded checkpoint it came from (``stylizer.Stylizer``)."""

    kernels: object  # model.skpn.StylizingKernels, batch of one
    decoder: dict  # "<index>.weight"/"<index>.bias" -> tensor: the tuned decoder convolutions
    colour_match: object | None  # colour_match.ColourMatch
    thumbnail: np.ndarray  # (H, W, 3) uint8 display RGB
    meta: dict  # checkpoint digest and name, density scale, orbit, key frame shape, settings, fit seconds
    noise_weight: object = None  # (3, noise channels) tensor, or None
    texture: object = None  # (3, tz, ty, tx) tensor over the box, or None
    stylizer: object = field(default=None, repr=False)
    _network: object = field(default=None, repr=False)
    _prepared_frames: dict = field(default_factory=dict, repr=False)  # frame_key -> prepare_frame's dict

    @property
    def density_scale(self) -> float:
        return float(self.meta["density_scale"])

    @property
    def camera_distance(self) -> float:
        return float(self.meta["camera_distance"])

    @property
    def style(self) -> np.ndarray:
        """The style picture ``(H, W, 3)`` float32 in [0, 1] the look was fitted to (its thumbnail)."""
        return self.thumbnail.astype(np.float32) / 255.0

    @property
    def network(self):
        """The SKPN the look applies: the checkpoint's, with the tuned decoder convolutions."""
        if self._network is None:
            model = self.stylizer.trained.model
            if self.decoder:
                model = copy.deepcopy(model)
                model.decoder.load_state_dict({**model.decoder.state_dict(), **self.decoder})
            self._network = model.eval()
        return self._network

    def network_albedo(self, grid: np.ndarray, phases: list | None = None) -> np.ndarray:
        """The tuned network's albedo ``(Z, Y, X, 3)`` of ``grid (Z, Y, X)``, before the colour match; its
        texture read through ``phases`` (``advection.TextureMotion.phases``) where given."""
        import torch

        with torch.no_grad():
            frame = self._prepared_frames.get(frame_key(grid))
            if frame is None:
                frame = prepare_frame(self.network, grid, self.meta.get("scale_structures", 1.0), self.noise_spec())
            albedo = frame_albedo(self.network, frame, self.kernels, self.noise_weight, self.texture, phases=phases)
        return np.ascontiguousarray(albedo.permute(1, 2, 3, 0).clamp(0, 1).cpu().numpy(), dtype=np.float32)

    def noise_spec(self) -> tuple[int, int] | None:
        """``(channels, seed)`` of the look's noise fields, or None."""
        channels = int(self.meta.get("noise_channels", 0))
        return (channels, int(self.meta.get("noise_seed", 0))) if channels else None

    def stylize(
        self, density, density_scale: float | None = None, notes: list | None = None, velocities=None
    ) -> np.ndarray | list[np.ndarray]:
        """Albedo ``(Z, Y, X, 3)`` of one density frame, or a list of them for a sequence ``(T, Z, Y, X)``
        or a list of frames: the tuned network, then the look's colour match. ``velocities`` (one
        ``(Z, Y, X, 3)`` per frame, voxels per frame, ``warp``'s convention): the texture travels with
        them (``advection``). ``density_scale`` (the scale the frames will be rendered at) other than
        the look's adds a note, as does a frame of a very different size from the key frames."""
        from .advection import TextureMotion
        from .stylizer import checked_frames

        grids, sequence = checked_frames(density)
        if notes is not None:
            notes.extend(self.notes_for(grids[0].shape, density_scale))
        if velocities is not None and len(velocities) != len(grids):
            raise ValueError(f"Need one velocity per frame, got {len(velocities)} for {len(grids)} frames.")
        motion = None if velocities is None or not sequence else TextureMotion(list(velocities))
        albedos = [self.apply(grid, None if motion is None else motion.phases(i)) for i, grid in enumerate(grids)]
        return albedos if sequence else albedos[0]

    def apply(self, grid: np.ndarray, phases: list | None = None) -> np.ndarray:
        """``stylize`` of one checked ``(Z, Y, X)`` float32 grid; its texture read through ``phases``
        (``advection.TextureMotion.phases``: the frame's advected fields) where given."""
        albedo = self.network_albedo(grid, phases)
        return albedo if self.colour_match is None else self.colour_match.apply(albedo, grid)

    def notes_for(self, shape: tuple, density_scale: float | None) -> list[str]:
        """What a user should know before applying the look to frames of ``shape`` at ``density_scale``."""
        notes = []
        if density_scale is not None and abs(density_scale - self.density_scale) > DENSITY_SCALE_TOLERANCE * max(
            1.0, self.density_scale
        ):
            notes.append(
                f"the look was fitted at density scale {self.density_scale:g} and these frames render at "
                f"{density_scale:g}: the medium's colours will show lighter or darker than fitted; refit the "
                f"look at {density_scale:g} (--save-look with --density-scale) to keep them"
            )
        fitted = max(self.meta["key_frame_shape"])
        ratio = max(shape) / fitted
        if ratio > SIZE_RATIO_NOTE or ratio < 1.0 / SIZE_RATIO_NOTE:
            notes.append(
                f"the look was fitted on {fitted}-voxel frames and this one is {max(shape)} voxels across: its "
                f"patterns come out {'finer' if ratio > 1 else 'coarser'} relative to the medium; "
                f"--scale-structures {1 / ratio:.3g} at fit time, or fitting on frames of this size, keeps them"
            )
        return notes

    # ------------------------------------------------------------------------ files
    def to_bytes(self) -> bytes:
        """The look as a weights-only ``torch.save`` file (tensors, numbers, strings; no pickled code)."""
        import torch

        match = None
        if self.colour_match is not None:
            match = {
                "log_levels": torch.from_numpy(np.asarray(self.colour_match.log_levels, np.float64)),
                "shown_levels": torch.from_numpy(np.asarray(self.colour_match.shown_levels, np.float64)),
                "stages": [
                    [torch.from_numpy(np.asarray(part, np.float64)) for part in stage]
                    for stage in self.colour_match.stages
                ],
            }
        record = {
            "format": LOOK_FORMAT,
            "version": LOOK_VERSION,
            "kernels": {
                str(site): {key: value.detach().cpu().float().clone() for key, value in parts.items()}
                for site, parts in self.kernels.sites.items()
            },
            "decoder": {key: value.detach().cpu().float().clone() for key, value in self.decoder.items()},
            "colour_match": match,
            "noise_weight": None if self.noise_weight is None else self.noise_weight.detach().cpu().float().clone(),
            "texture": None if self.texture is None else self.texture.detach().cpu().half().clone(),
            "thumbnail": torch.from_numpy(np.ascontiguousarray(self.thumbnail, np.uint8)),
            "meta": {key: value for key, value in self.meta.items() if key != "file_sha256"},
        }
        record[PAYLOAD_DIGEST_KEY] = payload_digest(record)
        buffer = io.BytesIO()
        torch.save(record, buffer)
        return buffer.getvalue()

    def save(self, path) -> Path:
        """Write the look to ``path`` (any file name), atomically."""
        from .io import atomic_write_bytes

        path = Path(path)
        if path.is_dir():
            raise ValueError(f"--save-look {path} is a folder; give a file name such as {path / 'style.look'}.")
        if not path.parent.is_dir():
            raise ValueError(f"The folder of --save-look {path} does not exist; create it or choose another path.")
        if (path.exists() or path.is_symlink()) and not is_look_file(path):
            raise ValueError(
                f"{path} already exists and is not a mistyle look; a look replaces only a look. Choose another path."
            )
        data = self.to_bytes()
        atomic_write_bytes(path, data)
        self.meta["file_sha256"] = hashlib.sha256(data).hexdigest()
        return path

    @classmethod
    def load(cls, path, stylizer=None, checkpoint=None, device: str = "cpu") -> Look:
        """The look in ``path``, bound to ``stylizer`` (a ``stylizer.Stylizer``) or to ``checkpoint``'s
        network (None: the bundled one). ``ValueError`` (one line) for a file that is not a look, a
        look of another format version, a look fitted with another network, or a damaged look: one whose
        tensors or meta no longer match the digest recorded at save (``payload_digest``), or whose tensors
        have the wrong shape for the network, NaN or infinite values, or values beyond ``MAX_LOOK_VALUE``."""
        import torch

        from .colour_match import ColourMatch
        from .model.skpn import StylizingKernels, site_key
        from .stylizer import Stylizer

        path = Path(path)
        if not path.is_file():
            raise ValueError(f"Look {path} does not exist; fit one with mistyle-render ... --save-look {path}.")
        try:
            data = path.read_bytes()
            record = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
        except Exception as error:  # torch raises many types for a damaged or foreign file
            text = str(error)
            if "WeightsUnpickler error:" in text:  # past torch's advice to unpickle unsafely, no fix for damage
                text = text.split("WeightsUnpickler error:", 1)[1].split("Check the documentation", 1)[0]
            reason = " ".join(text.split())[:120] or type(error).__name__
            raise ValueError(
                f"{path} is not a readable mistyle look ({reason}); fit it again with mistyle-render --save-look."
            ) from None
        if not isinstance(record, dict) or record.get("format") != LOOK_FORMAT:
            raise ValueError(f"{path} is not a mistyle look; fit one with mistyle-render --style S --save-look {path}.")
        if record.get("version") != LOOK_VERSION:
            raise ValueError(
                f"{path} is a look of format version {record.get('version')}, and this mistyle reads version "
                f"{LOOK_VERSION}; fit it again with this mistyle (mistyle-render --style S --save-look {path})."
            )
        check_look_record(record, path)
        try:
            meta = dict(record["meta"])
            kernels = StylizingKernels(
                {
                    site_key(site): {key: value.float() for key, value in parts.items()}
                    for site, parts in record["kernels"].items()
                }
            )
            decoder = {key: value.float() for key, value in record["decoder"].items()}
            thumbnail = record["thumbnail"].numpy()
            noise_weight = record.get("noise_weight")
            texture = record.get("texture")
            match = record["colour_match"]
            if match is not None:
                match = ColourMatch(
                    match["log_levels"].numpy(),
                    match["shown_levels"].numpy(),
                    tuple(tuple(part.numpy() for part in stage) for stage in match["stages"]),
                )
            meta["density_scale"], meta["key_frame_shape"], meta["checkpoint_sha256"]  # noqa: B018
        except (KeyError, TypeError, AttributeError, ValueError) as error:
            raise ValueError(
                f"{path} is a damaged mistyle look (missing {error}); fit it again with --save-look."
            ) from None
        meta["file_sha256"] = hashlib.sha256(data).hexdigest()  # which file a render came from
        stylizer = stylizer if stylizer is not None else Stylizer(checkpoint, device)
        digest = checkpoint_digest(stylizer.path)
        if digest != meta["checkpoint_sha256"]:
            raise ValueError(
                f"{path} was fitted with the network {meta.get('checkpoint_name', '?')} (SHA-256 "
                f"{meta['checkpoint_sha256'][:12]}), not {stylizer.path.name} ({digest[:12]}); pass that "
                "checkpoint with --checkpoint, or fit the look again with this one."
            )
        _check_network_shapes(kernels, decoder, stylizer.trained.model, path)
        kernels = StylizingKernels(
            {
                site: {key: value.to(stylizer.device) for key, value in parts.items()}
                for site, parts in kernels.sites.items()
            }
        )
        decoder = {key: value.to(stylizer.device) for key, value in decoder.items()}
        noise_weight = None if noise_weight is None else noise_weight.float().to(stylizer.device)
        texture = None if texture is None else texture.float().to(stylizer.device)
        return cls(kernels, decoder, match, thumbnail, meta, noise_weight, texture, stylizer=stylizer)


def _record_tensors(value, name: str = ""):
    """``(name, tensor)`` of every tensor in a look record (nested dicts and lists), in a fixed order; the
    name is the path, e.g. ``kernels/3/gamma``."""
    import torch

    if torch.is_tensor(value):
        yield name, value
    elif isinstance(value, dict):
        for key in sorted(value, key=str):
            yield from _record_tensors(value[key], f"{name}/{key}".lstrip("/"))
    elif isinstance(value, (list, tuple)):
        for index, item in enumerate(value):
            yield from _record_tensors(item, f"{name}/{index}".lstrip("/"))


def payload_digest(record: dict) -> str:
    """SHA-256 of a look record's tensors (each one's name, type, shape and bytes, in ``_record_tensors``'
    order) and of its meta: what ``to_bytes`` records under ``PAYLOAD_DIGEST_KEY``. torch's archives keep
    no checksum of their data, so without it a changed byte loads as a changed number."""
    import json

    import torch

    digest = hashlib.sha256()
    for name, tensor in _record_tensors({k: v for k, v in record.items() if k not in ("meta", PAYLOAD_DIGEST_KEY)}):
        data = tensor.detach().cpu().contiguous().reshape(-1)
        digest.update(f"{name}|{data.dtype}|{tuple(tensor.shape)}|".encode())
        digest.update(data.view(torch.uint8).numpy().tobytes())
    digest.update(json.dumps(record.get("meta"), sort_keys=True, default=str).encode())
    return digest.hexdigest()


def check_look_record(record: dict, path) -> None:
    """``ValueError`` (one line naming ``path``) for a look record that is damaged: a digest that does
    not match (``payload_digest``), a tensor with NaN, infinite or implausibly large values
    (``MAX_LOOK_VALUE``), a tensor of the wrong shape, or meta the renders cannot use. Shapes that depend on
    the network are checked once it is known (``Look.load``)."""
    import torch

    def damaged(what: str) -> ValueError:
        return ValueError(f"{path} is a damaged mistyle look ({what}); fit it again with --save-look.")

    recorded = record.get(PAYLOAD_DIGEST_KEY)
    if recorded is not None and recorded != payload_digest(record):
        raise damaged("its tensors or meta differ from the SHA-256 recorded when it was saved: the file changed")
    for name, tensor in _record_tensors({k: v for k, v in record.items() if k != "meta"}):
        if not (tensor.is_floating_point() or tensor.dtype == torch.uint8):
            raise damaged(f"its tensor {name} holds {tensor.dtype} values")
        if not tensor.is_floating_point():
            continue
        values = tensor.detach().double()
        bad = int((~torch.isfinite(values)).sum())
        if bad:
            raise damaged(f"its tensor {name} {tuple(tensor.shape)} holds {bad} NaN or infinite values")
        largest = float(values.abs().max()) if values.numel() else 0.0
        if largest > MAX_LOOK_VALUE:
            raise damaged(
                f"its tensor {name} holds values up to {largest:.4g}; a fitted look's stay within {MAX_LOOK_VALUE:g}"
            )

    def shaped(name: str, value, rank: int, first: int | None = None):
        if not torch.is_tensor(value) or value.dim() != rank or (first is not None and value.shape[0] != first):
            shape = tuple(value.shape) if torch.is_tensor(value) else type(value).__name__
            raise damaged(f"{name} has the shape {shape}, not {rank}-D{'' if first is None else f' of {first}'}")
        return value

    thumbnail = record.get("thumbnail")
    if thumbnail is not None:
        shaped("its thumbnail", thumbnail, 3)
        if thumbnail.dtype != torch.uint8 or thumbnail.shape[2] != 3 or min(thumbnail.shape[:2]) < 1:
            raise damaged(f"its thumbnail is {tuple(thumbnail.shape)} {thumbnail.dtype}, not (H, W, 3) uint8")
    match = record.get("colour_match")
    if isinstance(match, dict):
        levels = shaped("its colour match's response", match.get("shown_levels"), 1)
        if shaped("its colour match's albedo levels", match.get("log_levels"), 1).shape != levels.shape:
            raise damaged("its colour match's albedo and response levels differ in number")
        if len(levels) < 2 or bool((levels[1:] < levels[:-1]).any()):
            raise damaged("its colour match's response does not increase with the albedo")
        for number, stage in enumerate(match.get("stages") or []):
            if not isinstance(stage, (list, tuple)) or len(stage) != 3:
                raise damaged(f"its colour match's stage {number} is not (direction, source, target)")
            shaped(f"its colour match's stage {number} direction", stage[0], 1, 3)
            source = shaped(f"its colour match's stage {number} source", stage[1], 1)
            target = shaped(f"its colour match's stage {number} target", stage[2], 1)
            if target.shape != source.shape or len(source) < 2 or bool((source[1:] < source[:-1]).any()):
                raise damaged(f"its colour match's stage {number} is not a monotone map")
    if record.get("texture") is not None:
        shaped("its texture", record["texture"], 4, 3)
    meta = record.get("meta")
    if isinstance(meta, dict):
        noise_weight = record.get("noise_weight")
        if noise_weight is not None:
            shaped("its noise weights", noise_weight, 2, 3)
            if noise_weight.shape[1] != int(meta.get("noise_channels", noise_weight.shape[1])):
                raise damaged(f"its noise weights {tuple(noise_weight.shape)} do not match its noise channels")
        for key in ("density_scale", "camera_distance"):
            value = meta.get(key)
            if value is not None and not (isinstance(value, (int, float)) and 0 < value < math.inf):
                raise damaged(f"its {key.replace('_', ' ')} is {value!r}, not a finite number > 0")
        frame_shape = meta.get("key_frame_shape")
        if frame_shape is not None and not (
            isinstance(frame_shape, (list, tuple))
            and len(frame_shape) == 3
            and all(isinstance(n, int) and n >= 1 for n in frame_shape)
        ):
            raise damaged(f"its key frame shape is {frame_shape!r}, not three sizes >= 1")


def _check_network_shapes(kernels, decoder: dict, model, path) -> None:
    """``ValueError`` when a look's kernels or tuned convolutions do not have the shapes ``model`` (the
    checkpoint's SKPN) gives and takes."""
    from .model.skpn import NOISE_SITE

    def damaged(what: str) -> ValueError:
        return ValueError(f"{path} is a damaged mistyle look ({what}); fit it again with --save-look.")

    expected = {}
    for site in model.sites:
        predictor = model.predictors[str(site)]
        c, k = predictor.channels, predictor.kernel_size
        expected[site] = {"gamma": (1, c), "beta": (1, c)}
        if predictor.with_kernel:
            expected[site].update(weight=(1, c, c, k, k, k), bias=(1, c))
    noise = getattr(model, "noise_predictor", None)
    if noise is not None:
        expected[NOISE_SITE] = {"weight": (1, 3, noise.channels)}
    found = {site: {key: tuple(value.shape) for key, value in parts.items()} for site, parts in kernels.sites.items()}
    if found != expected:
        wrong = sorted(
            f"{site}/{key} {found.get(site, {}).get(key)}"
            for site in set(found) | set(expected)
            for key in set(found.get(site, {})) | set(expected.get(site, {}))
            if found.get(site, {}).get(key) != expected.get(site, {}).get(key)
        )
        raise damaged(f"its kernels {', '.join(wrong)} do not have the shapes the network gives")
    parameters = model.decoder.state_dict()
    for key, value in decoder.items():
        if key not in parameters or tuple(value.shape) != tuple(parameters[key].shape):
            shape = tuple(parameters[key].shape) if key in parameters else "no such parameter"
            raise damaged(f"its decoder {key} is {tuple(value.shape)}; the network's is {shape}")


NOISE_SCALES = (1 / 64, 2 / 64)
"""The blur of a look's noise fields, as fractions of the grid's longest side (1 and 2 voxels at 64^3): the
scales of the strokes and grain the head can add where the density alone has none."""


def look_noise(shape: tuple, channels: int, seed: int):
    """``(channels, Z, Y, X)`` float32 tensor: Gaussian noise blurred at ``NOISE_SCALES`` in turn (channel
    ``c`` at scale ``c mod len``), each channel scaled to unit spread. Fixed in the grid's space."""
    import torch
    import torch.nn.functional as F

    generator = torch.Generator().manual_seed(int(seed))
    fields = torch.randn((channels, 1) + tuple(shape), generator=generator)
    out = []
    for channel in range(channels):
        voxels = max(NOISE_SCALES[channel % len(NOISE_SCALES)] * max(shape), 0.5)
        radius = max(1, int(np.ceil(3 * voxels)))
        taps = torch.exp(-0.5 * (torch.arange(-radius, radius + 1, dtype=torch.float32) / voxels) ** 2)
        taps = taps / taps.sum()
        field = fields[channel : channel + 1]
        for axis in range(3):
            kernel = taps.view((1, 1) + tuple(len(taps) if a == axis else 1 for a in range(3)))
            field = F.conv3d(field, kernel, padding=tuple(radius if a == axis else 0 for a in range(3)))
        out.append(field[0, 0] / field.std().clamp_min(1e-12))
    return torch.stack(out)


def frame_key(grid: np.ndarray) -> tuple:
    """A frame's identity for a look's cache of what its fit computed of the key frames."""
    data = np.ascontiguousarray(grid, dtype=np.float32).data
    return tuple(grid.shape), hashlib.blake2b(data, digest_size=16).digest()


def prepare_frame(
    network,
    grid: np.ndarray,
    scale_structures: float = 1.0,
    noise=None,
    fixed_kernels=None,
    fixed_stage: str | None = None,
) -> dict:
    """What a look's network computes of one frame before its tuned parts: the (resampled, cropped)
    density's encoder features, its crop window, the noise fields on the padded crop (``noise``:
    ``(channels, seed)``) and, with ``fixed_kernels``, the decoder up to ``fixed_stage``
    (``LookSettings.fixed_stage``: the values a fit that tunes only what follows reuses; at ``"body"``
    also what ``frame_albedo`` needs to fold the head into one convolution,
    ``SKPN.folded_head_logits``)."""
    import torch
    import torch.nn.functional as F

    from .model.skpn import DEFAULT_CROP_MARGIN, occupied_window

    device = next(network.parameters()).device
    tensor = torch.from_numpy(np.ascontiguousarray(grid, dtype=np.float32))[None, None].to(device)
    if scale_structures != 1.0:
        size = tuple(max(4, round(n * scale_structures)) for n in grid.shape)
        tensor = F.interpolate(tensor, size=size, mode="trilinear", align_corners=False)
    size = tuple(tensor.shape[2:])
    window = occupied_window(tensor, DEFAULT_CROP_MARGIN)
    part = tensor if window is None else tensor[(..., *window)]
    fixed = {"body": None, "folded": None, "site": None, "logits": None}
    stages = ("body", "site", "logits")
    reached = stages.index(fixed_stage) + 1 if fixed_kernels is not None and fixed_stage is not None else 0
    with torch.no_grad():
        # A look's kernels never weigh the network's noise site (fit_look starts them without_noise and
        # does not tune it), so its fields, made for the whole grid, would add zeros.
        encoded = network.encode(part, noise_site=False)
        if reached >= 1:
            fixed["body"] = network.decode_body(encoded, fixed_kernels)
            if reached == 1 and network.folds_head(fixed_kernels):
                fixed["folded"] = network.fold_head_input(fixed["body"], encoded)
        if reached >= 2:
            fixed["site"] = network.head_site(fixed["body"], fixed_kernels, encoded)
        if reached >= 3:
            fixed["logits"] = network.head_logits(fixed["site"], fixed_kernels, encoded)
    fields = None
    if noise is not None:
        fields = look_noise(size, *noise).to(device)
        if window is not None:
            fields = fields[(slice(None), *window)]
        padded = encoded.features[0].shape[2:]
        fields = F.pad(fields, [p for n, m in reversed(list(zip(fields.shape[1:], padded))) for p in (0, m - n)])[None]
    return {"grid": grid, "size": size, "window": window, "encoded": encoded, "noise": fields, **fixed}


def coarse_frame(frame: dict, factor: int) -> dict | None:
    """``frame`` (``prepare_frame`` with the head folded) at 1/``factor`` of its resolution, for a look's
    coarse steps (``LookSettings.coarse_steps``), or None where its head is not folded.

    The folded features are put back on the whole grid (repeating the crop's faces, as ``uncrop`` does
    the albedo) and averaged over ``factor``^3 blocks, as is the density. The head's convolution then
    runs on ``factor``^3 fewer voxels with the same weights. What it computes there is close to the
    fine albedo averaged but not equal (its 3^3 kernel spans ``factor`` times the distance), so coarse
    steps only start a fit that fine steps finish."""
    import torch
    import torch.nn.functional as F

    from .model.skpn import FoldedBody, uncrop

    folded = frame["folded"]
    if folded is None:
        return None
    crop = frame["encoded"].size
    features = folded.features[..., : crop[0], : crop[1], : crop[2]].contiguous()
    whole = uncrop(features, frame["window"], frame["size"])
    pooled = F.avg_pool3d(whole, factor, ceil_mode=True)
    grid = torch.from_numpy(np.ascontiguousarray(frame["grid"], dtype=np.float32))[None, None]
    coarse_grid = F.avg_pool3d(grid, factor, ceil_mode=True)[0, 0].numpy()
    size = tuple(pooled.shape[2:])
    encoded = frame["encoded"]._replace(size=size, noise=None)
    return {
        **frame,
        "grid": coarse_grid,
        "size": size,
        "window": None,
        "encoded": encoded,
        "noise": None,
        "folded": FoldedBody(pooled, folded.mean, folded.covariance),
        "patches": patch_matrix(pooled[0]),
    }


def patch_matrix(features):
    """``(D * H * W, C * 27)``: each voxel's 3^3 neighbourhood of ``features (C, D, H, W)`` (zero beyond the
    grid), ordered as a ``(O, C, 3, 3, 3)`` convolution weight flattens, so that a 3^3 convolution with
    padding 1 is one matrix product. Torch's CPU convolution takes a path about ten times slower for
    some small grids (those whose channels x depth x height are at most 20480, such as 17 x 32 x 32); a
    product with fixed features has no such case."""
    import torch
    import torch.nn.functional as F

    channels, depth, height, width = features.shape
    padded = F.pad(features, (1, 1, 1, 1, 1, 1))
    shifted = [
        padded[:, z : z + depth, y : y + height, x : x + width] for z in range(3) for y in range(3) for x in range(3)
    ]
    return torch.stack(shifted, dim=-1).permute(1, 2, 3, 0, 4).reshape(depth * height * width, channels * 27)


def stretch_texture(texture, frame: dict, padded: tuple):
    """A look's ``texture (C, tz, ty, tx)`` stretched over the box of ``frame`` (``prepare_frame``) as
    trilinear interpolation (``align_corners=False``) to the frame's grid would, cut to its crop window
    and zero-padded to ``padded`` (the head's grid): ``(C, *padded)``.

    Trilinear interpolation is separable, so it runs as one small matrix product per axis, each of
    whose rows holds one voxel's two interpolation weights; a fit step's interpolation and its gradient
    cost several times less than ``F.interpolate`` of the whole grid. The matrices are kept in
    ``frame`` (per texture shape)."""
    import torch
    import torch.nn.functional as F

    channels, *texels = texture.shape
    key = ("stretch", tuple(texels), padded)
    matrices = frame.get(key)
    if matrices is None:
        window = frame["window"] or tuple(slice(0, n) for n in frame["size"])
        matrices = []
        for count, size, rows, length in zip(texels, frame["size"], window, padded):
            identity = torch.eye(count, dtype=torch.float32, device=texture.device)[None]
            weights = F.interpolate(identity, size=size, mode="linear", align_corners=False)[0].T[rows]
            matrices.append(F.pad(weights, (0, 0, 0, length - weights.shape[0])))
        frame[key] = matrices
    along_z, along_y, along_x = matrices
    values = torch.matmul(along_y, torch.matmul(texture, along_x.T))  # (C, tz, Y, X)
    return torch.matmul(along_z, values.reshape(channels, texels[0], -1)).reshape(channels, *padded)


def advected_texture(texture, frame: dict, padded: tuple, phases: list):
    """``stretch_texture`` of a texture that travels with the flow: ``texture (C, tz, ty, tx)`` read at the
    frame's advected ``phases`` (``advection.blend_phases``) over its whole grid, cut to its crop window
    and zero-padded to ``padded``: ``(C, *padded)``."""
    import torch.nn.functional as F

    from .advection import blend_phases

    values = blend_phases(texture, phases, tuple(frame["size"]))
    if frame["window"] is not None:
        values = values[(slice(None), *frame["window"])]
    return F.pad(values, [p for n, m in reversed(list(zip(values.shape[1:], padded))) for p in (0, m - n)])


def frame_albedo(
    network, frame: dict, kernels, noise_weight=None, texture=None, whole: bool = True, phases: list | None = None
):
    """A look's albedo ``(3, Z, Y, X)`` of a ``prepare_frame`` frame (differentiable in ``kernels``, the
    tuned decoder layers, ``noise_weight (3, channels)`` and ``texture (3, tz, ty, tx)``, which is
    stretched over the box whatever its resolution, or read through the frame's advected ``phases``,
    ``advection``; the noise fields stay in the grid's place). ``whole=False``: only over the frame's
    crop window where it has one and its grid was not resampled (``cropped_fit``), as
    ``render_views(..., window=frame["window"])`` takes it."""
    import torch
    import torch.nn.functional as F

    from .model.skpn import head_albedo, uncrop

    encoded = frame["encoded"]
    logits = frame["logits"]
    if logits is None and frame.get("patches") is not None:
        weight = network.folded_head_weight(frame["folded"], kernels)[0]
        logits = torch.addmm(network.decoder[2].bias, frame["patches"], weight.reshape(weight.shape[0], -1).T)
        logits = logits.T.reshape(1, -1, *frame["size"])
    elif logits is None and frame["folded"] is not None and network.folds_head(kernels):
        logits = network.folded_head_logits(frame["folded"], kernels, encoded)
    elif logits is None:
        site = frame["site"]
        if site is None:
            body = frame["body"] if frame["body"] is not None else network.decode_body(encoded, kernels)
            site = network.head_site(body, kernels, encoded)
        logits = network.head_logits(site, kernels, encoded)
    offset = None
    if noise_weight is not None and frame["noise"] is not None:
        offset = torch.einsum("oc,bcdhw->bodhw", noise_weight, frame["noise"])
    if texture is not None:
        padded = tuple(logits.shape[2:])
        stretched = (
            stretch_texture(texture, frame, padded) if not phases else advected_texture(texture, frame, padded, phases)
        )[None]
        offset = stretched if offset is None else offset + stretched
    albedo = head_albedo(logits if offset is None else logits + offset, encoded.size)
    if not whole and cropped_fit(frame):
        return albedo[0]
    albedo = uncrop(albedo, frame["window"], frame["size"])
    shape = tuple(frame["grid"].shape)
    if frame["size"] != shape:
        albedo = F.interpolate(albedo, size=shape, mode="trilinear", align_corners=False)
    return albedo[0]


def cropped_fit(frame: dict) -> bool:
    """Whether a fit step on ``frame`` (``prepare_frame``) works on its crop window alone: the albedo, the
    layer's render (``render_views``' ``window``) and the smoothness term. Outside the window the albedo
    only repeats the window's faces, where the density is at most ``OCCUPIED_DENSITY``."""
    return frame["window"] is not None and tuple(frame["size"]) == tuple(frame["grid"].shape)


def solid_texture_start(style: np.ndarray, texels: tuple, strength: float, seed: int = 0):
    """A look's texture start ``(3, *texels)``: a solid texture of ``style`` (``mistyle.solid_texture``)
    over the box, each channel centred on its mean and scaled by ``strength`` (logits of the head)."""
    import torch

    from .solid_texture import SolidTextureSettings, solid_texture_of, texture_in_box

    solid = solid_texture_of(style, SolidTextureSettings(seed=seed))
    values = texture_in_box(solid, texels)
    values = strength * (values - values.reshape(-1, 3).mean(axis=0))
    return torch.from_numpy(np.ascontiguousarray(values.transpose(3, 0, 1, 2)))


def thumbnail_of(style: np.ndarray, side: int = THUMBNAIL_SIDE) -> np.ndarray:
    """``style (H, W, 3)`` in [0, 1] as uint8, its longest side at most ``side`` pixels."""
    from PIL import Image

    image = Image.fromarray((np.clip(style, 0, 1) * 255 + 0.5).astype(np.uint8))
    scale = side / max(image.size)
    if scale < 1:
        image = image.resize(
            (max(1, round(image.size[0] * scale)), max(1, round(image.size[1] * scale))), Image.LANCZOS
        )
    return np.asarray(image, dtype=np.uint8).copy()


def fit_look(
    stylizer,
    densities: Sequence[np.ndarray],
    style,
    *,
    key_frames: Sequence[int] | None = None,
    density_scale: float | None = None,
    camera_distance: float | None = None,
    scale_structures: float = 1.0,
    settings: LookSettings | None = None,
    notes: list | None = None,
    progress: Callable[[int, int, float], None] | None = None,
    style_names: list[str] | None = None,
    prepared: Callable[[int], object] | None = None,
) -> Look:
    """Fit a ``Look`` of ``style`` (an image or path, a mix ``[(style, weight)]`` or a ``style.Style``) on the
    ``key_frames`` (default ``default_key_frames``) of ``densities`` (checked ``(Z, Y, X)`` frames of one
    shape) with ``stylizer``'s network (``stylizer.Stylizer``). ``progress(step, steps, loss)`` after
    each step. ``style_names``: what the look calls its style (default: the image files' names).
    ``prepared(index)``: frame ``index`` prepared for the fast layer at ``density_scale``, when the
    caller keeps them (``pipeline.Frames.prepared``); else each key frame is prepared here."""
    import torch

    from .integrators import prepare_density
    from .model.skpn import StylizingKernels
    from .stops import raise_if_requested
    from .style import Style

    settings = LookSettings() if settings is None else settings
    started = time.perf_counter()
    densities = [np.asarray(d, dtype=np.float32) for d in densities]
    keys = default_key_frames(len(densities)) if key_frames is None else sorted(set(int(k) for k in key_frames))
    if not keys or not all(0 <= k < len(densities) for k in keys):
        raise ValueError(f"Key frames {keys} must lie within the sequence's frames 0-{len(densities) - 1}.")
    density_scale = stylizer.density_scale if density_scale is None else float(density_scale)
    config = stylizer.config
    camera_distance = config.render.camera_distance if camera_distance is None else float(camera_distance)
    scene = _FitScene(density_scale, camera_distance, config.render.radiance)
    style = Style.of(style, notes, style_names)
    target = style.target
    fit = _tuned_parameters(stylizer, style, target, densities[keys[0]].shape, settings)

    # Per key frame, what does not change during the fit: the encoder's features (and the decoder as far
    # as nothing in it is tuned, LookSettings.fixed_stage), the crop, the noise and the layer's Ls grid.
    fixed_kernels = StylizingKernels(fit.free) if settings.fixed_stage is not None else None
    frames = []
    for key in keys:
        raise_if_requested()
        frames.append(
            prepare_frame(fit.network, densities[key], scale_structures, fit.noise, fixed_kernels, settings.fixed_stage)
        )
    prepared_densities = []
    for key in keys:
        raise_if_requested()
        prepared_densities.append(prepare_density(densities[key], density_scale) if prepared is None else prepared(key))

    def fit_match(key_albedo):
        return _key_frame_match(key_albedo, [densities[key] for key in keys], target, scene, settings.seed, notes)

    match = None
    if settings.colour_match == "through":
        with torch.no_grad():
            match = fit_match(lambda index: fit.albedo(frames[index]).permute(1, 2, 3, 0).cpu().numpy())
    losses = _fit_steps(fit, frames, prepared_densities, match, target, scene, settings, notes, progress)

    kernels = StylizingKernels(
        {site: {key: value.detach() for key, value in kernel.items()} for site, kernel in fit.free.items()}
    )
    decoder = {
        f"{index}.{name}": value.detach().clone()
        for index in settings.tune_decoder
        for name, value in fit.network.decoder[index].named_parameters()
    }
    meta = {
        "checkpoint_sha256": checkpoint_digest(stylizer.path),
        "checkpoint_name": stylizer.path.name,
        "style": style.describe(),
        "density_scale": density_scale,
        "camera_distance": camera_distance,
        "scale_structures": float(scale_structures),
        "key_frames": keys,
        "key_frame_shape": list(densities[keys[0]].shape),
        "frames_seen": len(densities),
        "settings": {
            key: list(value) if isinstance(value, tuple) else value for key, value in asdict(settings).items()
        },
        "final_loss": losses[-1] if losses else None,
    }
    noise_weight, texture = fit.noise_weight, fit.texture
    if fit.noise is not None:
        meta.update(noise_channels=settings.noise_channels, noise_seed=settings.seed)
        noise_weight = noise_weight.detach().clone()
    if texture is not None:
        texture = texture.detach().half().float()  # as the file keeps it
    look = Look(kernels, decoder, match, thumbnail_of(target), meta, noise_weight, texture, stylizer=stylizer)
    if settings.fixed_stage is not None:
        # What the fit computed once per key frame (encoder features, the decoder up to its fixed stage)
        # is what applying the look computes first, as nothing tuned enters it: kept, applying the look to
        # a key frame (a single frame's default output) computes only the rest, by the plain path.
        for key, frame in zip(keys, frames):
            look._prepared_frames[frame_key(densities[key])] = {**frame, "folded": None}
    if settings.colour_match == "after":
        raise_if_requested()
        look.colour_match = fit_match(lambda index: look.network_albedo(densities[keys[index]]))
    look.meta["fit_seconds"] = time.perf_counter() - started
    return look


@dataclass(frozen=True)
class _FitScene:
    """What a look's fit renders its key frames with: the density scale, the orbit's radius, the light."""

    density_scale: float
    camera_distance: float
    radiance: float


@dataclass
class _TunedParameters:
    """What a look's fit changes (the network's copy with its tuned decoder convolutions, the free kernels,
    the noise weights, the texture) and its optimizer."""

    network: object
    device: object  # torch.device
    free: dict
    noise: tuple | None  # (channels, seed) of the noise fields, or None
    noise_weight: object
    texture: object
    optimizer: object

    def albedo(self, frame: dict, whole: bool = True):
        from .model.skpn import StylizingKernels

        return frame_albedo(self.network, frame, StylizingKernels(self.free), self.noise_weight, self.texture, whole)


def _tuned_parameters(stylizer, style, target: np.ndarray, shape: tuple, settings: LookSettings):
    """The network's copy and the parameters a look's fit tunes on key frames of ``shape``
    (``_TunedParameters``), started as ``settings`` say."""
    import torch

    from .adam import Adam

    device = stylizer.device
    # A look's own texture does what the network's noise site does, fitted to the style: started with the
    # site's noise, looks came out worse (docs/decisions/2026-12-02-noise-site.md), so a look starts without it.
    initial = stylizer.kernels(style).without_noise()
    network = copy.deepcopy(stylizer.trained.model).float().eval()
    for parameter in network.parameters():
        parameter.requires_grad_(False)
    tuned = []
    for index in settings.tune_decoder:
        for parameter in network.decoder[index].parameters():
            parameter.requires_grad_(True)
            tuned.append(parameter)
    free = {
        site: {
            key: value.detach().clone().float().requires_grad_(key != "bias" and site in settings.tune_sites)
            for key, value in kernel.items()
        }
        for site, kernel in initial.sites.items()
    }
    parameters = [value for kernel in free.values() for value in kernel.values() if value.requires_grad] + tuned
    noise = (settings.noise_channels, settings.seed) if settings.noise_channels else None
    noise_weight = None
    if noise is not None:
        noise_weight = torch.zeros((3, settings.noise_channels), device=device, requires_grad=True)
        parameters.append(noise_weight)
    groups = [{"params": parameters, "lr": settings.lr}]
    texture = None
    if settings.texture_side:
        longest = max(shape)
        texels = tuple(max(1, round(n * settings.texture_side / longest)) for n in shape)
        generator = torch.Generator().manual_seed(settings.seed)
        start = settings.texture_init * torch.randn((3,) + texels, generator=generator)
        if settings.texture_start == "solid":
            start = start + solid_texture_start(target, texels, settings.texture_start_strength, settings.seed)
        texture = start.to(device).requires_grad_(True)
        groups.append({"params": [texture], "lr": settings.texture_lr})
    return _TunedParameters(network, device, free, noise, noise_weight, texture, Adam(groups))


def _key_frame_match(key_albedo, key_densities: list, target, scene: _FitScene, seed: int, notes: list | None):
    """The colour match fitted on the first key frame the layer sees (``key_albedo(index)``: the albedo
    of key frame ``index``); a simulation's first frame can be a wisp too thin to see."""
    from .colour_match import InvisibleMedium, fit_colour_match

    for index, density in enumerate(key_densities):
        try:
            return fit_colour_match(
                key_albedo(index),
                density,
                target,
                density_scale=scene.density_scale,
                radiance=scene.radiance,
                camera_distance=scene.camera_distance,
                seed=seed,
            )
        except InvisibleMedium:
            continue
    if notes is not None:
        notes.append("the look has no colour match: its key frames are too thin to be seen at this density scale")
    return None


def _fit_steps(fit, frames, prepared_densities, match, target, scene, settings, notes, progress) -> list[float]:
    """The fit's Adam steps on ``frames`` (``prepare_frame``'s, in turn) through the fast layer against the
    sliced objective with the body mask, plus the smoothness term; returns each step's loss."""
    import torch

    from .bridge_torch import render_views
    from .integrators import prepare_density
    from .model.features import square_style
    from .model.skpn import inference_precision
    from .objective.losses import tv_loss
    from .objective.masks import body_mask
    from .objective.style import SLICED_STYLE_SIZE, SlicedObjective
    from .scenes import CameraPath
    from .stops import raise_if_requested

    device = fit.device
    # Coarse steps first, on the key frames at a lower resolution (coarse_frame), where each frame allows it.
    coarse = [coarse_frame(frame, settings.coarse_factor) for frame in frames] if settings.coarse_steps else []
    coarse_steps = settings.coarse_steps if coarse and all(frame is not None for frame in coarse) else 0
    if settings.coarse_steps and not coarse_steps and notes is not None:
        notes.append("the look's coarse steps were skipped: they need the head folded (LookSettings' defaults)")
    if coarse_steps:
        coarse_densities = [prepare_density(frame["grid"], scene.density_scale) for frame in coarse]
    insides = [
        torch.from_numpy((frame["grid"][frame["window"]] if cropped_fit(frame) else frame["grid"]) > 0).to(device)
        for frame in frames
    ]
    coarse_insides = [torch.from_numpy(frame["grid"] > 0).to(device) for frame in coarse] if coarse_steps else []
    if inference_precision(device) == "bf16":
        # The fit's one convolution in bfloat16 where the hardware computes it natively, as the network
        # runs at inference: 2-4x faster on this project's CPU. The look is applied in float32.
        frames = [{**f, "folded": f["folded"].in_bfloat16()} if f["folded"] is not None else f for f in frames]
    objective = SlicedObjective(
        rgb_weight=settings.rgb_weight,
        patch_weight=settings.patch_weight,
        seed=settings.seed,
        direction_pool=settings.direction_pool,
        structure_weight=settings.structure_weight,
        # The style's gradients at the scale a final render shows it: its side over the views' side.
        structure_style_pool=max(1, round(SLICED_STYLE_SIZE / settings.layer_res)),
    )
    targets = objective.targets(square_style(target, SLICED_STYLE_SIZE).to(device)[None])
    orbit, rng = CameraPath(distance=scene.camera_distance), np.random.default_rng(settings.seed)
    render = dict(steps=settings.layer_steps_per_ray, radiance=scene.radiance)
    optimizer, losses = fit.optimizer, []
    base_rates = [group["lr"] for group in optimizer.groups]
    parameters = [parameter for group in optimizer.groups for parameter in group["params"]]
    best_loss, best_values = math.inf, None
    total = coarse_steps + settings.steps
    for step in range(total):
        raise_if_requested()
        if settings.lr_schedule == "cosine":
            for group, rate in zip(optimizer.groups, base_rates):
                group["lr"] = rate * 0.5 * (1.0 + math.cos(math.pi * step / total))
        key = step % len(frames)
        if step < coarse_steps:
            frame, prepared, inside = coarse[key], coarse_densities[key], coarse_insides[key]
            layer_res = max(8, settings.layer_res // settings.coarse_factor)
        else:
            frame, prepared, inside = frames[key], prepared_densities[key], insides[key]
            layer_res = settings.layer_res
        if settings.view_sampling == "stratified":
            views = orbit.sample_stratified(settings.views_per_step, rng)
        else:
            views = orbit.sample(settings.views_per_step, rng)
        # On the crop window where the frame has one: the albedo outside it repeats its faces, which the
        # render takes as the padded grid (render_views' window); the smoothness term is the crop's
        # part of the grid's mean.
        window = frame["window"] if cropped_fit(frame) else None
        albedo = fit.albedo(frame, whole=window is None)
        if match is not None:
            albedo = match.apply_torch(albedo, inside)
        images, white = render_views(albedo, prepared, views, layer_res, white=True, window=window, **render)
        smoothness = tv_loss(albedo[None]) * (albedo[0].numel() / frame["grid"].size)
        loss = objective.loss(images[None], targets, body_mask(white)) + settings.tv_weight * smoothness
        optimizer.zero_grad()
        loss.backward()
        losses.append(float(loss.detach()))
        if losses[-1] < best_loss:  # the values this step's loss was computed with, before the step
            best_loss, best_values = losses[-1], [parameter.detach().clone() for parameter in parameters]
        optimizer.step()
        if progress is not None:
            progress(step + 1, total, losses[-1])
    if diverged(losses):
        with torch.no_grad():
            for parameter, value in zip(parameters, best_values):
                parameter.copy_(value)
        if notes is not None:
            notes.append(
                f"the look's fit diverged (its last steps' loss above its start's): it keeps the values of "
                f"its lowest loss, {best_loss:.4g}, at step {losses.index(best_loss) + 1} of {len(losses)}"
            )
    return losses


DIVERGENCE_WINDOW = 10
"""Steps whose mean loss a fit's start and end are compared by (``diverged``)."""


def diverged(losses: Sequence[float]) -> bool:
    """Whether a fit's ``losses`` (one a step) end higher than they started: the mean of the last
    ``DIVERGENCE_WINDOW`` steps (of the last half, for a short fit) above the first step's, the loss
    of the start. A fit that converges ends below its start (0.09-0.99 of it on 56 of the benchmark's
    63 pairs, ``results/look_divergence/``); one that diverged, as the gradient term did on
    a few styles of fine, high-contrast texture by pinning the head's colours at its bounds within a
    few steps (a flat colour whose only gradients are the silhouette's), ends above it. Each step's
    loss is measured on other random views, so the end is a mean over steps."""
    window = min(DIVERGENCE_WINDOW, len(losses) // 2)
    return window > 0 and float(np.mean(losses[-window:])) > losses[0]


def is_look_file(path) -> bool:
    """Whether ``path`` is a file mistyle saved as a look (the only file ``--save-look`` may replace)."""
    import zipfile

    import torch

    path = Path(path)
    if not path.is_file() or path.is_symlink() or not zipfile.is_zipfile(path):  # torch's archives are zips
        return False
    try:
        record = torch.load(path, map_location="cpu", weights_only=True)
    except Exception:  # a damaged or foreign archive: not a look either way
        return False
    return isinstance(record, dict) and record.get("format") == LOOK_FORMAT
