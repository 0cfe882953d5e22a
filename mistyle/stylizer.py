"""The network as a library: a loaded checkpoint (``Stylizer``) and what every stage checks of its inputs.

``Stylizer`` maps a density and a style (an image, or a mix of images) to the SKPN's albedo, then
gives it the style's colours (``mistyle.colour_match``); ``pipeline.Pipeline`` and ``look.Look``
build on it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .style import Style

PACKAGE = Path(__file__).resolve().parent
DEFAULT_CHECKPOINT = PACKAGE / "checkpoints" / "skpn_noise.pt"
"""The bundled network: recipe ``skpn_noise`` (``mistyle.train.recipes``), ``skpn_cpu.pt`` with a noise site."""
SCALE_STRUCTURES_RANGE = (0.125, 8.0)
# Rec. 709 luma of display RGB: the brightness a neutral (strength 0) medium keeps from the style.
LUMA_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])


def validate_scale_structures(factor, name: str = "scale_structures") -> float:
    """The structure-scale factor, in ``SCALE_STRUCTURES_RANGE``; ``ValueError`` naming ``name``."""
    low, high = SCALE_STRUCTURES_RANGE
    if not (np.isfinite(factor) and low <= factor <= high):
        raise ValueError(f"{name} must lie in [{low}, {high}], got {factor}.")
    return float(factor)


def validate_strength(strength, name: str = "strength") -> float:
    """A style strength in [0, 1]; ``ValueError`` naming ``name``."""
    if not (np.isfinite(strength) and 0.0 <= strength <= 1.0):
        raise ValueError(f"{name} must lie in [0, 1] (0: a uniform grey medium, 1: the full style), got {strength}.")
    return float(strength)


class Stylizer:
    """A loaded checkpoint: ``stylizer(density, style) -> albedo``; see ``stylize``.

    Attributes:
        trained: the checkpoint's ``mistyle.model.checkpoint.TrainedModel`` (network, config,
            extractor, density scale).
    """

    def __init__(self, checkpoint=None, device: str = "cpu", vgg_weights=None):
        import torch

        from .model.checkpoint import load_model

        path = Path(checkpoint) if checkpoint is not None else DEFAULT_CHECKPOINT
        if not path.is_file():
            if checkpoint is None:
                raise ValueError(
                    f"The bundled checkpoint {path} is missing; train one with "
                    "`python -m mistyle.train --config configs/cpu.toml --out runs/cpu` and pass --checkpoint."
                )
            raise ValueError(
                f"Checkpoint {path} does not exist; give a file written by `python -m mistyle.train` "
                "(e.g. runs/cpu/final.pt), or leave --checkpoint out for the bundled one."
            )
        self.trained = load_model(path, vgg_weights)
        self.device = torch.device(device)
        self.trained.model.to(self.device)
        self.trained.extractor.to(self.device)

    @property
    def path(self) -> Path:
        return self.trained.path

    @property
    def config(self):
        return self.trained.config

    @property
    def extractor(self):
        return self.trained.extractor

    @property
    def density_scale(self) -> float:
        return self.trained.density_scale

    def style_tensor(self, style: np.ndarray):
        """``(H, W, 3)`` style -> the ``(3, S, S)`` square the network and the objective see."""
        from .model.features import square_style

        return square_style(style, self.config.data.style_size)

    def style_inputs(self, style: np.ndarray):
        """What the network reads of ``style`` (``model.skpn.StyleInputs``)."""
        return self.trained.model.encode_style(self.style_tensor(style)[None].to(self.device), self.extractor)

    def kernels(self, style, notes: list | None = None):
        """The stylizing kernels (``model.skpn.StylizingKernels``) the network applies for ``style``:
        one image or path, a mix ``[(style, weight)]`` or a ``style.Style``, whose kernels are blended with the
        weights normalised to sum 1."""
        import torch

        from .model.skpn import StylizingKernels

        model = self.trained.model
        with torch.no_grad():
            return StylizingKernels.blend(
                [
                    (model.predict_kernels(self.style_inputs(image)), weight)
                    for image, weight in Style.of(style, notes).parts
                ]
            )

    def weakened(self, kernels, grid: np.ndarray, strength: float, neutral=None):
        """``kernels`` at ``strength``: blended with ``SKPN.neutral_kernels`` whose grey is the luma of the
        full-strength albedo's density-weighted mean on ``grid``, so that fading the style out keeps
        the medium's brightness and removes its hues and patterns (0: uniform grey, 1: ``kernels``).
        ``neutral``: ``self.neutral(kernels, grid)`` when the caller has it already (a slider's steps)."""
        from .model.skpn import StylizingKernels

        if validate_strength(strength) == 1.0:
            return kernels
        neutral = self.neutral(kernels, grid) if neutral is None else neutral
        return StylizingKernels.blend([(kernels, strength), (neutral, 1.0 - strength)])

    def neutral(self, kernels, grid: np.ndarray):
        """``SKPN.neutral_kernels`` of ``kernels`` whose grey is the luma of the density-weighted mean of
        the albedo ``kernels`` give on ``grid`` (what ``weakened`` fades towards)."""
        full = self.network_albedo(grid, kernels, 1.0)
        grey = float(np.tensordot(grid / grid.sum(), full, axes=3) @ LUMA_WEIGHTS)
        return self.trained.model.neutral_kernels(kernels, grey)

    def __call__(
        self,
        density,
        style,
        scale_structures: float = 1.0,
        notes: list | None = None,
        strength: float = 1.0,
        match_colours: bool = True,
        density_scale: float | None = None,
        camera_distance: float | None = None,
    ) -> np.ndarray:
        """Albedo ``(Z, Y, X, 3)`` (or ``(T, Z, Y, X, 3)``) of ``density`` for ``style`` (see ``kernels``)
        at ``strength`` (see ``weakened``; a sequence's grey comes from its first frame that holds medium).
        A sequence's frames with too little medium to stylize (``holds_medium``) hold ``EMPTY_FRAME_ALBEDO``.

        ``match_colours``: give the network's arrangement the style's colours (``colour_match``; for a
        mix, the colours of ``style_target``), moved ``strength`` of the way, as the medium renders at
        ``density_scale`` seen from ``camera_distance`` (None: the checkpoint's); a sequence shares the
        map fitted on its first frame. A medium too thin to be seen keeps the network's colours (said in
        ``notes``). False: the network's albedo as predicted."""
        array = np.asarray(density)
        sequence = array.ndim == 4 and array.shape[-1] != 1
        grids, _ = checked_frames(list(array) if sequence else array)
        validate_scale_structures(scale_structures)
        validate_strength(strength)
        holding = holding_frames(grids)
        first = grids[holding[0]]
        light = self.colour_match_light(density_scale, camera_distance)
        matched = match_colours and strength > 0
        if matched:  # rendered while the network runs
            from .colour_match import grey_response_ahead

            response = grey_response_ahead(first, **light)
        style = Style.of(style, notes)
        inputs = self.weakened(self.kernels(style), first, strength)
        albedos = [self.network_albedo(grids[index], inputs, scale_structures) for index in holding]
        if matched:
            albedos = self.match_colours(
                albedos,
                [grids[index] for index in holding],
                style.target,
                strength,
                notes,
                density_scale=light["density_scale"],
                camera_distance=light["camera_distance"],
                response=response,
            )
        if not sequence:
            return albedos[0]
        stylized = dict(zip(holding, albedos))
        empty = empty_frame_albedo(first.shape)
        return np.stack([stylized.get(index, empty) for index in range(len(grids))])

    def colour_match_light(self, density_scale: float | None = None, camera_distance: float | None = None) -> dict:
        """The light the colour match renders the medium in: ``density_scale`` and ``camera_distance``
        (None: the checkpoint's) and the checkpoint's radiance, as ``grey_response`` takes them."""
        render = self.config.render
        return {
            "density_scale": self.density_scale if density_scale is None else density_scale,
            "radiance": render.radiance,
            "camera_distance": render.camera_distance if camera_distance is None else camera_distance,
        }

    def match_colours(
        self,
        albedos: list,
        grids: list,
        target: np.ndarray,
        strength: float = 1.0,
        notes: list | None = None,
        *,
        density_scale: float | None = None,
        camera_distance: float | None = None,
        response=None,
    ) -> list:
        """The frames' albedos ``[(Z, Y, X, 3)]`` on ``grids`` with the colours of the picture ``target (H, W, 3)``
        (``colour_match``), through the map fitted on the first frame the layer sees (a simulation's first
        frame can be a wisp), moved ``strength`` of the way. The map is fitted on renders at ``density_scale``
        from ``camera_distance``, the final render's (None: the checkpoint's). A medium too thin to be seen
        in every frame keeps its albedos (said in ``notes``). ``response``: the first frame's
        ``grey_response_ahead`` in this light, when the caller started it."""
        from .colour_match import InvisibleMedium, fit_colour_match

        light = self.colour_match_light(density_scale, camera_distance)
        for index, (albedo, grid) in enumerate(zip(albedos, grids)):
            try:
                shown = response.result() if index == 0 and response is not None else None
                match = fit_colour_match(albedo, grid, target, **light, response=shown)
            except InvisibleMedium:
                continue
            return [match.apply(albedo, grid, strength) for albedo, grid in zip(albedos, grids)]
        if notes is not None:
            notes.append(
                "colour match skipped: the medium is too thin to be seen at this density scale, "
                "so the network's own colours are kept"
            )
        return albedos

    def network_albedo(self, grid: np.ndarray, inputs, scale_structures: float = 1.0, model=None) -> np.ndarray:
        """The network's albedo ``(Z, Y, X, 3)`` of one checked ``grid (Z, Y, X)`` for ``inputs`` (kernels or
        style inputs), the density resampled by ``scale_structures``; ``model``: another SKPN than the
        checkpoint's (a look's tuned one)."""
        import torch
        import torch.nn.functional as F

        shape = grid.shape
        density = torch.from_numpy(grid)[None, None].to(self.device)
        if scale_structures != 1.0:
            size = tuple(max(4, round(n * scale_structures)) for n in shape)
            density = F.interpolate(density, size=size, mode="trilinear", align_corners=False)
        with torch.no_grad():
            model = self.trained.model if model is None else model
            albedo = model.infer(density, inputs)  # empty space cropped: SKPN.infer
            if tuple(albedo.shape[2:]) != shape:
                albedo = F.interpolate(albedo, size=shape, mode="trilinear", align_corners=False)
        return np.ascontiguousarray(albedo[0].permute(1, 2, 3, 0).clamp(0, 1).cpu().numpy(), dtype=np.float32)


def check_finite(what: str, arrays) -> None:
    """``ValueError`` naming the stage whose output holds NaN/inf, instead of handing it on."""
    for index, array in enumerate(arrays):
        if not np.all(np.isfinite(array)):
            raise ValueError(
                f"{what} {index} holds NaN/inf values; nothing was written. Check the density's range "
                "(normalise it and use --density-scale) and the light's strength."
            )


MIN_MEDIUM_VOXELS = 8
"""The fewest non-zero voxels the network stylizes (a medium a couple of voxels across)."""


def check_enough_medium(grid: np.ndarray, name: str = "density") -> None:
    """``ValueError`` for a medium of fewer than ``MIN_MEDIUM_VOXELS`` non-zero voxels.

    DAIN normalises the network's features by their spread over the medium; a single voxel has none,
    so the normalisation divides by ``sqrt(eps)`` at every level and the features overflow to NaN."""
    occupied = int(np.count_nonzero(grid))
    if occupied < MIN_MEDIUM_VOXELS:
        raise ValueError(
            f"The {name} holds too little medium to stylize: {occupied} non-zero voxel(s), fewer than "
            f"{MIN_MEDIUM_VOXELS}. The network normalises its features over the medium, and so few voxels give "
            "it no spread to measure. Give a volume whose medium spans a few voxels (or resample it larger)."
        )


def holds_medium(grid: np.ndarray) -> bool:
    """Whether a density frame holds enough medium to stylize (``MIN_MEDIUM_VOXELS`` non-zero voxels)."""
    return int(np.count_nonzero(grid)) >= MIN_MEDIUM_VOXELS


def holding_frames(grids) -> list[int]:
    """The indices of the frames of ``grids`` that hold medium enough to stylize (``holds_medium``)."""
    return [index for index, grid in enumerate(grids) if holds_medium(grid)]


EMPTY_FRAME_ALBEDO = 0.5
"""The albedo, in every voxel and channel, of a sequence's frame that holds too little medium to stylize
(``holds_medium``): a frame before a simulation's emitter starts, or a few voxels of its first puff."""


def empty_frame_albedo(shape: tuple) -> np.ndarray:
    """The albedo ``(*shape, 3)`` of a frame of grid ``shape`` that holds too little medium to stylize."""
    return np.full(tuple(shape) + (3,), EMPTY_FRAME_ALBEDO, np.float32)


def frame_list(indices: list[int]) -> str:
    """Frame indices as a message names them: ``3-40`` for a run, else ``1, 5, 9``."""
    first, last = indices[0], indices[-1]
    run = last > first and list(indices) == list(range(first, last + 1))
    return f"{first}-{last}" if run else ", ".join(map(str, indices))


def checked_frames(density, names: list[str] | None = None, chunk: bool = False) -> tuple[list[np.ndarray], bool]:
    """``(grids, sequence)``: ``density`` (one ``(Z, Y, X)`` array, a sequence ``(T, Z, Y, X)`` or a list of
    frames) as checked float32 frames, and whether it was a sequence; ``names``: the frames' names in
    messages. ``ValueError`` for a frame that is not a valid density, or a single frame that is all zero or
    holds too little medium. A sequence's frames may hold too little medium to stylize (``holds_medium``: a
    simulation's frames before its emitter starts; they are rendered as they are, ``EMPTY_FRAME_ALBEDO``) as
    long as one of them holds enough, or (``chunk``: frames of a longer sequence, whose others may) none does."""
    from .volume import validate_density

    listed = isinstance(density, (list, tuple))
    array = density if listed else np.asarray(density)
    items = list(array) if listed else list(array) if array.ndim == 4 and array.shape[-1] != 1 else [array]
    sequence = listed or len(items) > 1
    grids = []
    for index, frame in enumerate(items):
        if names is not None:
            name = f"density {names[index]}"
        else:
            name = f"density frame {index}" if len(items) > 1 else "density"
        grids.append(validate_density(frame, name=name))
    if len(grids) == 1 and not chunk:
        if not grids[0].any():
            raise ValueError(f"The {name} is all zero; there is no medium to stylize or render.")
        check_enough_medium(grids[0], name)
    elif not chunk and not holding_frames(grids):
        held = [index for index, grid in enumerate(grids) if grid.any()]
        few = f" (frame(s) {frame_list(held)} hold fewer than {MIN_MEDIUM_VOXELS} non-zero voxels)" if held else ""
        raise ValueError(
            f"None of the sequence's {len(grids)} frames holds medium enough to stylize{few}. "
            "Check the folder (a cache of another domain, or frames before the simulation starts)."
        )
    return grids, sequence
