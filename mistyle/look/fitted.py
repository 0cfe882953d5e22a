"""A fitted look (``Look``): applied to frames, saved and loaded, its file checked."""

from __future__ import annotations

import copy
import hashlib
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..resample import DEFAULT_WORKING_SIZE, WorkingGrid, validate_working_size
from .frames import frame_albedo, frame_key, prepare_frame

LOOK_FORMAT = "mistyle-look"
LOOK_VERSION = 1
SIZE_RATIO_NOTE = 2.0
"""A frame more than this many times larger or smaller (longest side) than the key frames gets a note."""
DENSITY_SCALE_TOLERANCE = 1e-6
PAYLOAD_DIGEST_KEY = "payload_sha256"
"""Where a saved look records ``payload_digest`` of its tensors and meta; ``Look.load`` checks it (looks saved
before it was recorded load without, checked for shape, finiteness and magnitude only)."""
MAX_LOOK_VALUE = 1e4
"""The largest magnitude a look's numbers may have. A fit moves the network's kernels and convolutions, the
texture and the colour tables by amounts of order one; a value beyond this is damage, and it would overflow
the network's float32 statistics (DAIN) into NaN albedos."""


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
                frame = prepare_frame(self.network, grid, self.meta.get("scale_structures", 1.0))
            albedo = frame_albedo(self.network, frame, self.kernels, self.texture, phases=phases)
        return np.ascontiguousarray(albedo.permute(1, 2, 3, 0).clamp(0, 1).cpu().numpy(), dtype=np.float32)

    def stylize(
        self,
        density,
        density_scale: float | None = None,
        notes: list | None = None,
        velocities=None,
        working_size: int = DEFAULT_WORKING_SIZE,
    ) -> np.ndarray | list[np.ndarray]:
        """Albedo ``(Z, Y, X, 3)`` of one density frame, or a list of them for a sequence ``(T, Z, Y, X)``
        or a list of frames: the tuned network, then the look's colour match. ``velocities`` (one
        ``(Z, Y, X, 3)`` per frame, voxels per frame, ``warp``'s convention): the texture travels with
        them (``advection``). ``density_scale`` (the scale the frames will be rendered at) other than
        the look's adds a note, as does a frame of a very different size from the key frames. Frames
        longer than ``working_size`` on a side are stylized on a copy resampled to it, their albedo
        resampled back (``mistyle.resample``; 0: the full grid). A sequence's frames with too little
        medium to stylize (``stylizer.holds_medium``) hold ``stylizer.EMPTY_FRAME_ALBEDO``."""
        from ..advection import TextureMotion
        from ..stylizer import checked_frames, empty_frame_albedo, holds_medium

        grids, sequence = checked_frames(density)
        if velocities is not None and len(velocities) != len(grids):
            raise ValueError(f"Need one velocity per frame, got {len(velocities)} for {len(grids)} frames.")
        validate_working_size(working_size)
        working = [WorkingGrid.of(grid.shape, working_size) for grid in grids]
        grids = [grid if work is None else work.density(grid) for grid, work in zip(grids, working)]
        if velocities is not None:
            velocities = [v if work is None else work.velocity(v) for v, work in zip(velocities, working)]
        if notes is not None:
            notes.extend(self.notes_for(grids[0].shape, density_scale))
        motion = None if velocities is None or not sequence else TextureMotion(list(velocities))
        albedos = [
            self.apply(grid, None if motion is None else motion.phases(i))
            if holds_medium(grid)
            else empty_frame_albedo(grid.shape)
            for i, grid in enumerate(grids)
        ]
        albedos = [a if work is None else work.albedo(a, grid) for a, grid, work in zip(albedos, grids, working)]
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
        from ..files import atomic_write_bytes

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

        from ..colour_match import ColourMatch
        from ..model.skpn import StylizingKernels, site_key
        from ..stylizer import Stylizer

        path = Path(path)
        if not path.is_file():
            raise ValueError(f"Look {path} does not exist; fit one with mistyle-render ... --save-look {path}.")
        data = path.read_bytes()
        if not data.startswith(b"PK\x03\x04"):  # torch's archives are zip files; anything else is not a look
            raise ValueError(
                f"{path} is not a mistyle look (the file is not one --save-look writes); fit one with "
                f"mistyle-render --style S --save-look {path.name}."
            )
        try:
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
        texture = None if texture is None else texture.float().to(stylizer.device)
        return cls(kernels, decoder, match, thumbnail, meta, texture, stylizer=stylizer)


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
    if record.get("noise_weight") is not None:  # a study's look of 2026-12 (LookSettings.noise_channels, removed)
        raise ValueError(
            f"{path} is a look with noise fields, which only a study fitted and this mistyle no longer applies; "
            "fit it again with --save-look."
        )
    meta = record.get("meta")
    if isinstance(meta, dict):
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
    from ..model.skpn import NOISE_SITE

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
