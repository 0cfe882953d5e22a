"""Colour matching: the network's arrangement, the style's colours (a closed-form stage after the SKPN).

The SKPN decides where colours go in the medium, but it gives every style much the same colours: it
stores all the styles it trained on in one set of weights
(docs/decisions/2026-11-25-training-notebook.md, "A colour match after the network", measured with
experiments/gap_decomposition.py).
This stage keeps the network's arrangement and gives it the style's colours, without a gradient
step: a map of colour, fitted from a grey response sweep and one low-resolution render of the
matched medium.

1. **Response.** Under a white light every colour channel renders independently, so one sweep of
   uniform grey albedos ``a`` (``RESPONSE_LEVELS``, path traced with ``volpath`` from one view, three
   levels a render, one in each channel) gives ``f(a)``: the mean display value of the medium's
   foreground (``response.uniform_display_response``).
   Each voxel's albedo is mapped to the colour ``f(albedo)`` a medium of that albedo would show.
2. **Weights.** A voxel counts in proportion to how much of it the orbit's cameras see: its density
   times its mean transmittance from the four horizontal sides of the box (``visible_weight``); on
   the validation pairs it beat density weights (``results/output_corrections/``).
3. **Transport.** An iterated sliced optimal transport (Pitie et al. 2007, "Automated colour grading
   using colour distribution transfer") carries the weighted distribution of shown colours onto
   the style's pixel colours: ``TRANSPORT_ROUNDS`` rounds of three orthogonal random directions, each
   a monotone 1-D map between ``TRANSPORT_QUANTILES`` quantiles.
4. **Feedback.** The transport matches voxels, not pixels: a pixel mixes the voxels along its ray
   (so the rendered colours come out narrower than the voxels'), a pixel on the fringe mixes in the
   background, and the response is a mean over a small render's foreground. So the albedo the
   transport gives is path traced once, from ``FEEDBACK_VIEWS`` views evenly around the orbit
   (``FEEDBACK_RES``:sup:`2`, ``FEEDBACK_SPP`` paths per pixel, one launch), and a second sliced
   transport (``FEEDBACK_ROUNDS`` rounds), carrying that render's foreground display colours onto
   the style's pixels, is appended to the map: every voxel's shown colour moves by it too. An affine
   map commutes with the averages along rays, so for the map's affine part one round is exact.
   With and without it on the validation pairs: ``results/colour_match_feedback/``
   (``experiments/colour_match_feedback.py``).
5. Each occupied voxel moves by its displacement under the whole map times ``strength`` and maps back
   through ``f^{-1}`` (interpolated in log albedo). Empty voxels keep their albedo.

The map is fitted once (``fit_colour_match``) and is a function of colour only, so a sequence's
frames share the first frame's map (``ColourMatch.apply``); the albedo flicker still rises with the
contrast the match adds (docs/decisions/2026-11-25-training-notebook.md). Everything is seeded: the
same inputs give the same albedo.

Shapes: density ``(Z, Y, X)``, albedo ``(Z, Y, X, 3)`` in [0, 1], style ``(H, W, 3)`` display values
in [0, 1].
"""

from __future__ import annotations

import hashlib
import os
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np

from .volume import box_of

RESPONSE_LEVELS = tuple(np.geomspace(1e-2, 1.0, 9))
"""Grey albedos of the response sweep; albedos below the first are matched as the first."""
RESPONSE_VIEW = 0.0
"""Orbit position of the response render (the response is a mean over the foreground, so one view serves)."""
TRANSPORT_ROUNDS = 12
TRANSPORT_QUANTILES = 65
TRANSPORT_SAMPLES = 16384
"""Voxels (drawn by weight) and style pixels the transport is fitted on."""
TRANSPORT_BLOCK = 32768
"""Colours carried through every stage at a time (``apply_sliced_transport``, ``ColourMatch.applied``): a
block and its temporaries stay in the core's cache, where whole arrays through one stage at a time went
to memory and back once a stage (1.7x the time at 128^3, the same values)."""
FEEDBACK_VIEWS = 8
"""Views of the feedback render, evenly around the orbit from position 0."""
FEEDBACK_RES = 32
FEEDBACK_SPP = 16
"""Paths per pixel of the feedback render. With fewer, a thin medium's fringe pixels are black or sparse
bright samples, so the feedback sees a brighter, wider foreground than the converged render users get,
and its correction darkens and dulls the colours: 16 against 4 gave the default output RGB SWD 0.82x on
28 validation pairs; 64 cost patch error (``results/feedback_spp_study/``)."""
FEEDBACK_ROUNDS = 4
"""Rounds of the feedback transport (it corrects a distribution already near the style's)."""


def visible_weight(density: np.ndarray, density_scale: float) -> np.ndarray:
    """``(Z, Y, X)``: density times the mean transmittance from the four horizontal sides (the box's
    ``-X, +X, -Z, +Z`` faces, which the orbit's cameras look through) to each voxel's centre."""
    density = np.asarray(density, dtype=np.float64)
    if density.ndim != 3:
        raise ValueError(f"density must be (Z, Y, X), got shape {density.shape}.")
    weight = np.zeros_like(density)
    # Computed over the medium's box alone: outside it the density and so the weight are zero, and the
    # sums along an axis from a face reach the box through zeros, which add nothing (the same values).
    box = box_of(density != 0)
    if box is None:
        return weight
    inside = density[box]
    depth = inside * float(density_scale) / max(density.shape)  # optical depth of one voxel (longest side 1)
    transmittance = np.zeros_like(inside)
    for axis in (0, 2):
        for flipped in (False, True):
            step = np.flip(depth, axis) if flipped else depth
            seen = np.exp(-(np.cumsum(step, axis=axis) - 0.5 * step))
            transmittance += np.flip(seen, axis) if flipped else seen
    weight[box] = inside * transmittance / 4.0
    return weight


def fit_sliced_transport(
    source: np.ndarray, target: np.ndarray, rng: np.random.Generator, rounds: int = TRANSPORT_ROUNDS
) -> list:
    """Iterated sliced optimal transport of the samples ``source (N, 3)`` onto ``target (M, 3)``: a list
    of stages ``(direction (3,), source quantiles, target quantiles)``, for ``apply_sliced_transport``."""
    current, levels, stages = np.array(source, dtype=np.float64), np.linspace(0, 1, TRANSPORT_QUANTILES), []
    target = np.asarray(target, dtype=np.float64)
    for _ in range(rounds):
        basis, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        for direction in basis.T:
            stage = (direction, quantiles(current @ direction, levels), quantiles(target @ direction, levels))
            stages.append(stage)
            current = apply_sliced_transport([stage], current)
    return stages


def quantiles(values: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """``np.quantile(values, levels)`` (its default, linear method) from one sort: ten times faster for
    this stage's 65 levels, whose many partitions cost more than a sort."""
    ordered = np.sort(values)
    position = np.asarray(levels) * (len(ordered) - 1)
    below = np.minimum(position.astype(np.intp), len(ordered) - 2)
    return ordered[below] + (position - below) * (ordered[below + 1] - ordered[below])


def apply_sliced_transport(stages: list, colours: np.ndarray) -> np.ndarray:
    """``colours (N, 3)`` carried through ``stages`` (``fit_sliced_transport``). Each colour moves on its
    own, so a long list is carried in blocks of ``TRANSPORT_BLOCK`` consecutive colours (``_in_blocks``)."""
    current = np.array(colours, dtype=np.float64)

    def carry(begin: int) -> None:
        _carried(stages, current[begin : begin + TRANSPORT_BLOCK])  # in place

    _in_blocks(carry, len(current))
    return current


def _in_blocks(carry, count: int) -> None:
    """``carry(begin)`` for ``begin`` in ``range(0, count, TRANSPORT_BLOCK)``, on a thread per core (numpy
    releases the interpreter lock in the transport's loops). Each block's colours go through every stage
    while they stay in the core's cache."""
    starts = range(0, count, TRANSPORT_BLOCK)
    workers = min(os.cpu_count() or 1, len(starts))
    if workers < 2:
        for begin in starts:
            carry(begin)
        return
    with ThreadPoolExecutor(workers) as pool:
        for _ in pool.map(carry, starts):
            pass


def _carried(stages: list, current: np.ndarray) -> np.ndarray:
    """``current (N, 3)`` carried through ``stages``, in place (and returned)."""
    for direction, source, target in stages:
        projected = current @ direction
        current += (np.interp(projected, source, target) - projected)[:, None] * direction
    return current


class InvisibleMedium(ValueError):
    """The response render sees no medium (a density too thin for its scale): there are no colours to match."""


@dataclass(frozen=True)
class _Resume:
    """Where ``ColourMatch.applied`` left an albedo: its ``digest`` (``digest_of``) and each medium voxel's
    shown colour carried through the first ``done`` stages, ``carried (N, 3)`` in the order of
    ``np.flatnonzero`` of the medium."""

    digest: bytes
    carried: np.ndarray
    done: int

    @staticmethod
    def digest_of(albedo: np.ndarray, inside: np.ndarray) -> bytes:
        """A digest of ``albedo`` and of where the medium is: another albedo, or the same one on another
        medium, never resumes."""
        digest = hashlib.blake2b(digest_size=16)
        digest.update(repr((albedo.shape, inside.shape)).encode())
        digest.update(np.ascontiguousarray(albedo).view(np.uint8))
        digest.update(np.packbits(inside))
        return digest.digest()


@dataclass(frozen=True)
class ColourMatch:
    """A fitted colour match: the grey response ``f`` (``log_levels`` -> ``shown_levels``) and the transport
    stages (``fit_sliced_transport``), in shown colour. ``resume``, when given, is ``_Resume``: the
    albedo the match was fitted on (by its digest) and its voxels' shown colours carried through the
    first stages, which the fit already computed; ``apply`` on that albedo goes on from there (the same
    result, fewer stages to run)."""

    log_levels: np.ndarray
    shown_levels: np.ndarray
    stages: tuple
    resume: _Resume | None = field(default=None, compare=False, repr=False)

    def shown(self, albedo: np.ndarray) -> np.ndarray:
        """``f(albedo)`` per channel."""
        return np.interp(np.log(np.clip(albedo, RESPONSE_LEVELS[0], 1.0)), self.log_levels, self.shown_levels)

    def apply(self, albedo: np.ndarray, density: np.ndarray, strength: float = 1.0) -> np.ndarray:
        """``albedo (Z, Y, X, 3)`` with every voxel where ``density > 0`` moved ``strength`` of the way
        along its transport displacement (module docstring); float32."""
        return self.applied(albedo, density, strength, resumable=False)[0]

    def applied(
        self, albedo: np.ndarray, density: np.ndarray, strength: float = 1.0, resumable: bool = True
    ) -> tuple[np.ndarray, _Resume | None]:
        """``apply``'s albedo, and (``resumable``) the ``resume`` of that albedo through all the stages.

        The map moves each colour on its own, so the medium's voxels are carried in blocks of
        ``TRANSPORT_BLOCK``, a block a core at a time, each through every stage and back to albedo, in
        place: beside the albedo it returns, the match holds the medium's voxel indices, a block's
        temporaries a core and (``resumable``) the carried colours, never a copy of the grid's colours
        (``results/bench_scale/colour_match.jsonl``)."""
        result = np.array(albedo, dtype=np.float32)
        inside = np.asarray(density) > 0
        voxels = np.flatnonzero(inside)
        # Digested only where it can serve: an albedo over another number of medium voxels is not the fitted one.
        resume = self.resume
        if resume is not None and len(resume.carried) != len(voxels):
            resume = None
        digest = _Resume.digest_of(result, inside) if resume is not None or resumable else None
        start, done = (resume.carried, resume.done) if resume is not None and resume.digest == digest else (None, 0)
        carried = np.empty((len(voxels), 3)) if resumable else None
        colours, stages, lowest, highest = result.reshape(-1, 3), self.stages[done:], *self.shown_levels[[0, -1]]

        def carry(begin: int) -> None:
            block = voxels[begin : begin + TRANSPORT_BLOCK]
            shown = self.shown(colours[block].astype(np.float64))
            moving = _carried(stages, (shown if start is None else start[begin : begin + len(block)]).copy())
            if carried is not None:
                carried[begin : begin + len(block)] = moving
            moved = np.clip(shown + float(strength) * (moving - shown), lowest, highest)
            colours[block] = np.exp(np.interp(moved, self.shown_levels, self.log_levels))

        _in_blocks(carry, len(voxels))
        return result, _Resume(digest, carried, len(self.stages)) if resumable else None

    def apply_torch(self, albedo, inside):
        """``apply`` at strength 1 on a torch ``albedo (3, Z, Y, X)``, differentiable (the map is piecewise
        linear in shown colour), where the boolean ``inside (Z, Y, X)`` holds; float32 ``(3, Z, Y, X)``.
        A look's fit optimises the network through it (``mistyle.look``)."""
        import torch

        def table(values):
            return torch.as_tensor(np.asarray(values), dtype=torch.float64, device=albedo.device)

        stages = [tuple(table(part) for part in stage) for stage in self.stages]
        return carry_torch(albedo, inside, table(self.log_levels), table(self.shown_levels), stages)


def carry_torch(albedo, inside, log_levels, shown_levels, stages):
    """``albedo (3, Z, Y, X)`` where ``inside (Z, Y, X)`` holds, through the response ``log_levels`` ->
    ``shown_levels`` and the transport ``stages`` (float64 tensors) and back: ``ColourMatch.apply_torch``'s
    arithmetic, for stages that are constants or functions of the albedo (``fit_colour_match_torch``)."""
    colours = albedo.permute(1, 2, 3, 0)[inside].double()  # (N, 3)
    carried = interpolate(colours.clamp(RESPONSE_LEVELS[0], 1.0).log(), log_levels, shown_levels)
    for direction, source, target in stages:
        projected = carried @ direction
        carried = carried + (interpolate(projected, source, target) - projected)[:, None] * direction
    moved = carried.clamp(float(shown_levels[0]), float(shown_levels[-1]))
    matched = interpolate(moved, shown_levels, log_levels).exp()
    result = albedo.permute(1, 2, 3, 0).clone()
    result[inside] = matched.to(albedo.dtype)
    return result.permute(3, 0, 1, 2)


@dataclass(frozen=True)
class TorchColourMatch:
    """A colour match without feedback fitted in torch on the albedo it is applied to
    (``fit_colour_match_torch``): ``stages``' source quantiles are functions of that albedo."""

    log_levels: object  # torch float64 (L,)
    shown_levels: object
    stages: tuple  # (direction (3,), source quantiles (Q,), target quantiles (Q,)), float64 tensors

    def apply(self, albedo, inside):
        """``albedo (3, Z, Y, X)`` matched where ``inside`` holds (``carry_torch``)."""
        return carry_torch(albedo, inside, self.log_levels, self.shown_levels, self.stages)

    def detached(self) -> TorchColourMatch:
        """The same map, passing no gradient to the albedo it was fitted on."""
        return replace(self, stages=tuple(tuple(part.detach() for part in stage) for stage in self.stages))


def transport_samples(density, style, density_scale: float, rng: np.random.Generator) -> tuple:
    """What a fit's transport is fitted on, drawn from ``rng`` in this order: ``TRANSPORT_SAMPLES`` flat
    voxel indices of ``density (Z, Y, X)`` by ``visible_weight``, and as many of ``style``'s pixels
    ``(TRANSPORT_SAMPLES, 3)``. Both fits draw through it, so for one seed they fit the same map."""
    from .memo import kept

    pixels = np.asarray(style, dtype=np.float64).reshape(-1, 3)
    # Kept: the network's colour match and a look's fit on the same frame weigh the same voxels.
    density = np.asarray(density)
    scale = np.array([density_scale], dtype=np.float64)
    weight = kept("visible weight", (density, scale), lambda: visible_weight(density, density_scale)).ravel()
    voxels = rng.choice(weight.size, TRANSPORT_SAMPLES, p=weight / weight.sum())
    return voxels, pixels[rng.choice(len(pixels), TRANSPORT_SAMPLES)]


def fit_colour_match_torch(
    albedo, density: np.ndarray, style: np.ndarray, *, density_scale: float, response: np.ndarray, seed: int = 0
) -> TorchColourMatch:
    """``fit_colour_match(..., feedback=False)`` on the torch ``albedo (3, Z, Y, X)``, as a function of it.

    The transport's source quantiles are order statistics of the albedo's own shown colours (the same
    voxels, pixels and directions as the numpy fit draws for ``seed``, so the same map to rounding).
    A gradient of a loss on ``apply(albedo)`` then counts how the fit moves with the albedo as well as
    how the map moves each voxel: the part of a change that the refitted match would undo (a shift or
    stretch of the colour distribution) gets no gradient, and what is left is the arrangement, which
    the match keeps. Holding the map fixed instead (``ColourMatch.apply_torch`` on a fit of the
    detached albedo) tells a network to move colours the next fit moves back."""
    import torch

    device = albedo.device

    def table(values):
        return torch.as_tensor(np.asarray(values), dtype=torch.float64, device=device)

    rng = np.random.default_rng(seed)
    voxels, target = transport_samples(density, style, density_scale, rng)
    log_levels, shown_levels = table(np.log(RESPONSE_LEVELS)), table(np.asarray(response, dtype=np.float64))
    colours = albedo.permute(1, 2, 3, 0).reshape(-1, 3)[torch.as_tensor(voxels, device=device)].double()
    current = interpolate(colours.clamp(RESPONSE_LEVELS[0], 1.0).log(), log_levels, shown_levels)
    levels, stages = np.linspace(0, 1, TRANSPORT_QUANTILES), []
    for _ in range(TRANSPORT_ROUNDS):
        basis, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        for direction in basis.T:
            projected = current @ table(direction)
            stage = (table(direction), quantiles_torch(projected, levels), table(quantiles(target @ direction, levels)))
            stages.append(stage)
            current = current + (interpolate(projected, stage[1], stage[2]) - projected)[:, None] * stage[0]
    return TorchColourMatch(log_levels, shown_levels, tuple(stages))


def quantiles_torch(values, levels: np.ndarray):
    """``quantiles`` in torch, differentiable in ``values`` (through the sort)."""
    import torch

    ordered = torch.sort(values).values
    position = np.asarray(levels) * (len(ordered) - 1)
    below = np.minimum(position.astype(np.intp), len(ordered) - 2)
    fraction = torch.as_tensor(position - below, dtype=ordered.dtype, device=ordered.device)
    below = torch.as_tensor(below, device=ordered.device)
    return ordered[below] + fraction * (ordered[below + 1] - ordered[below])


MAX_SLOPE = 1e3
"""``interpolate`` passes no gradient through a segment steeper than this: the response's nearly equal levels
(a saturated medium; ``grey_response`` keeps them 1e-9 apart) would otherwise give gradients of 1e9 and more."""


def interpolate(x, xp, fp):
    """``np.interp`` in torch (``xp`` increasing, ties allowed; constant beyond its ends), differentiable in
    ``x``, ``xp`` and ``fp`` except on segments steeper than ``MAX_SLOPE`` (there the value is exact and
    the gradient zero)."""
    import torch

    index = torch.searchsorted(xp.detach().contiguous(), x.detach().contiguous()).clamp(1, len(xp) - 1)
    left, right, low, high = xp[index - 1], xp[index], fp[index - 1], fp[index]
    steep = (high - low).detach().abs() > MAX_SLOPE * (right - left).detach()
    x, left, right, low, high = (torch.where(steep, part.detach(), part) for part in (x, left, right, low, high))
    span = right - left
    safe = torch.where(span > 0, span, torch.ones_like(span))
    weight = torch.where(span > 0, (x - left) / safe, 1.0)
    value = low + weight.clamp(0.0, 1.0) * (high - low)
    return torch.where(x <= xp[0], fp[0], torch.where(x >= xp[-1], fp[-1], value))


def grey_response(density: np.ndarray, *, density_scale: float, radiance: float, camera_distance: float) -> np.ndarray:
    """Step 1 of the module docstring: the display value ``f(a)`` the medium shows at each of
    ``RESPONSE_LEVELS``, strictly increasing (so that it inverts). ``InvisibleMedium`` when no pixel
    of the response render sees the medium; ``ValueError`` above ``conventions.MAX_EXTINCTION``."""
    from .memo import kept
    from .response import uniform_display_response
    from .scenes import CameraPath
    from .volume import validate_extinction

    density = np.asarray(density, dtype=np.float32)
    validate_extinction(density, density_scale, "The density")  # a render's time grows with the extinction

    def rendered():
        try:
            shown_levels = uniform_display_response(
                density,
                density_scale,
                radiance,
                [CameraPath(distance=camera_distance).view(RESPONSE_VIEW)],
                RESPONSE_LEVELS,
                res=32,
                spp=4,
                pack_channels=True,
            )
        except ValueError as error:  # no pixel sees the medium
            raise InvisibleMedium(f"{error} The colour match needs a visible medium.") from None
        return shown_levels + np.arange(len(shown_levels)) * 1e-9

    # Kept: the network's colour match and a look's fit on the same frame ask for the same response.
    light = np.array([density_scale, radiance, camera_distance], dtype=np.float64)
    return kept("grey response", (density, light), rendered).copy()


_AHEAD: ThreadPoolExecutor | None = None


def grey_response_ahead(
    density: np.ndarray, *, density_scale: float, radiance: float, camera_distance: float
) -> Future:
    """``grey_response`` of ``density``, computed on a thread of its own while the caller goes on (the
    network, in torch, which releases the interpreter lock): it depends on the density and the light
    only, so its render and Dr.Jit's compilation of its kernels take the core torch leaves. The
    future's ``result()`` is ``grey_response``'s array, or raises what it raises."""
    global _AHEAD
    if _AHEAD is None:
        _AHEAD = ThreadPoolExecutor(1, thread_name_prefix="mistyle-response")
    light = {"density_scale": density_scale, "radiance": radiance, "camera_distance": camera_distance}
    return _AHEAD.submit(grey_response, np.array(density, dtype=np.float32), **light)


def fit_colour_match(
    albedo: np.ndarray,
    density: np.ndarray,
    style: np.ndarray,
    *,
    density_scale: float,
    radiance: float,
    camera_distance: float,
    seed: int = 0,
    feedback: bool = True,
    response: np.ndarray | None = None,
) -> ColourMatch:
    """The ``ColourMatch`` carrying the colours ``albedo (Z, Y, X, 3)`` shows on ``density (Z, Y, X)``
    onto ``style (H, W, 3)``'s (module docstring); ``feedback=False`` leaves out step 4. ``response``:
    ``grey_response``'s values for this density and light when the caller has them (they do not
    depend on the albedo or the style).

    Raises:
        ValueError: an albedo of another shape than the density's, or a density whose extinction (max
            density times ``density_scale``) exceeds ``conventions.MAX_EXTINCTION``, beyond which the
            renders' time has no useful bound.
        InvisibleMedium: a medium no pixel of the response render sees, even at albedo 1."""
    from .conventions import FOREGROUND_THRESHOLD
    from .response import albedo_renders
    from .scenes import CameraPath
    from .tone import display
    from .volume import validate_extinction

    density = np.asarray(density, dtype=np.float32)
    albedo = np.asarray(albedo, dtype=np.float32)
    if albedo.shape != density.shape + (3,):
        raise ValueError(
            f"albedo must be the density's shape plus 3 channels {density.shape + (3,)}, got {albedo.shape}."
        )
    validate_extinction(density, density_scale, "The density")
    orbit = CameraPath(distance=camera_distance)
    if response is None:
        response = grey_response(
            density, density_scale=density_scale, radiance=radiance, camera_distance=camera_distance
        )
    shown_levels = np.asarray(response, dtype=np.float64)
    rng = np.random.default_rng(seed)
    voxels, target = transport_samples(density, style, density_scale, rng)
    match = ColourMatch(np.log(RESPONSE_LEVELS), shown_levels, ())
    source = match.shown(albedo.reshape(-1, 3)[voxels].astype(np.float64))
    stages = fit_sliced_transport(source, target, rng)
    match = replace(match, stages=tuple(stages))
    if feedback:
        views = orbit.turntable(FEEDBACK_VIEWS)
        transported, resume = match.applied(albedo, density)
        (renders,) = albedo_renders(
            density, density_scale, radiance, views, [transported], res=FEEDBACK_RES, spp=FEEDBACK_SPP, batch=True
        )
        rendered = display(renders[renders.max(axis=-1) > FOREGROUND_THRESHOLD]).astype(np.float64)
        if len(rendered):  # the response saw the medium; a render of darker albedos may not
            pixels = np.asarray(style, dtype=np.float64).reshape(-1, 3)
            stages = fit_sliced_transport(
                rendered, pixels[rng.choice(len(pixels), TRANSPORT_SAMPLES)], rng, rounds=FEEDBACK_ROUNDS
            )
            match = replace(match, stages=match.stages + tuple(stages), resume=resume)
    return match
