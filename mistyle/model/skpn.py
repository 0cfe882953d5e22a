"""SKPN (paper Sec. 4.2): a stylizing kernel predictor (SKP) and a volume autoencoder (VolAE).

SKP: for each style feature level, the channel means and standard deviations go through three FC
layers (LeakyReLU) that predict a stylizing kernel: a ``k^3`` convolution ``C x C`` with its bias,
and the DAIN affine ``gamma, beta`` (``k^3 C^2 + 3 C`` numbers). With ``stylize="adain"`` only
``gamma, beta`` are predicted (AdaIN-style modulation, the paper's Fig. 15 comparison).

VolAE: an encoder of three 3^3 conv blocks (strides 1, 2, 2) with residual blocks and LeakyReLU,
and a mirrored decoder (trilinear x2 upsampling, skip connections, ReLU) ending in tanh mapped to
albedo in [0, 1]. Stylizing kernels act at the bottleneck and before the decoder's last three
convolutions: ``x <- DAIN(K * x + b; m) * gamma + beta``, with the density mask ``m`` at that
resolution. Any ``D, H, W`` is accepted: the volume is padded to a multiple of 4 and cropped back.

Style code: with ``style_code="moments"`` (the paper's) each predictor reads its level's moments
only; with ``"quantiles"`` also the style's quantile code (``model.style_code``), the same vector for
every site. ``SKPN.encode_style`` turns style images into what ``forward`` takes (``StyleInputs``).

Noise site (``model.noise_scales``; not in the paper): smooth noise fields fixed in the grid's box
(``model.noise``) are added before the decoder's tanh, weighted per albedo channel by a fifth
predictor from the shallowest style level and the code (``NoiseWeightPredictor``; its kernel is
``StylizingKernels.sites[NOISE_SITE]``). The density decides where the other sites' features vary;
the noise lets colour vary where it does not, at the scales (and, with ``model.noise_orientations``,
in the upright or layered shapes) each style weighs (``docs/decisions/2026-12-02-noise-site.md``).

Mixing and strength: ``SKPN.predict_kernels`` returns the SKP's output (``StylizingKernels``) and
``forward`` also takes it, so styles are combined where the model combines them: a convex
combination of predicted kernels (``StylizingKernels.blend``) is again a kernel set, and moves the
albedo continuously from one style's to the other's.

Shapes: density ``(B, 1, D, H, W)``; style levels ``[(B, C_l, H_l, W_l)]`` (4 levels) and code
``(B, CODE_SIZE)`` or None; output albedo ``(B, 3, D, H, W)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import torch
import torch.nn as nn
import torch.nn.functional as F

from ..conventions import PRECISIONS
from .dain import dain, dain_of_mixed, density_mask, masked_moments
from .noise import noise_fields, validate_noise_orientations, validate_noise_scales
from .style_code import CODE_SIZE, style_code

DEFAULT_CROP_MARGIN = 8
"""Voxels of empty space kept around the density's bounding box by ``SKPN.infer``."""
OCCUPIED_DENSITY = 1e-4
"""The density at or below which a voxel is left out of the box the network runs over (``occupied_window``).
Simulations leave such traces far from the smoke (the bundled smoke: 41% of its grid above zero, 7%
above 1e-2; its box above zero is 3.5x its box above this), and the network's cost grows with the box.
What leaving them out changes is bounded: DAIN weighs a voxel by ``1 - exp(-100 d^2)``, at most 1e-6
here, and they keep their density in every render, only their albedo becomes the box's faces', which
changes a ray through nothing but such voxels by at most ``density_scale * 1e-4 * sqrt(3)`` of its
light (0.35% at the default scale of 20)."""


@dataclass
class SKPNConfig:
    widths: tuple[int, int, int] = (16, 32, 64)  # encoder block widths (full, 1/2, 1/4 resolution)
    residual_blocks: int = 1  # per encoder block
    style_channels: tuple[int, int, int, int] = (64, 128, 256, 512)  # the extractor's level widths
    style_hidden: int = 256
    kernels: int = 4  # 1: bottleneck only; 2: + before the last conv; 4: bottleneck + last three
    kernel_size: int = 1
    norm: str = "dain"  # or "in"
    stylize: str = "kernel"  # or "adain"
    style_code: str = "moments"  # or "quantiles": feature moments plus the style's quantile code
    noise_scales: tuple[float, ...] = ()  # the noise site's field scales (fractions of the longest side); (): none
    noise_per_scale: int = 2  # fields at each scale
    noise_seed: int = 0
    noise_orientations: tuple[str, ...] = ("isotropic",)  # model.noise.NOISE_ORIENTATIONS, fields of each

    def __post_init__(self):
        if min(*self.widths, *self.style_channels, self.style_hidden) < 1 or self.residual_blocks < 0:
            sizes = f"{list(self.widths)}, {list(self.style_channels)}, {self.style_hidden}, {self.residual_blocks}"
            raise ValueError(f"widths, style_channels, style_hidden must be >= 1, residual_blocks >= 0; got {sizes}.")
        if self.kernels not in (1, 2, 4):
            raise ValueError(f"kernels must be 1, 2 or 4, got {self.kernels}.")
        if self.kernel_size not in (1, 3):
            raise ValueError(f"kernel_size must be 1 or 3, got {self.kernel_size}.")
        if self.norm not in ("dain", "in") or self.stylize not in ("kernel", "adain"):
            raise ValueError(f"norm must be dain|in and stylize kernel|adain, got {self.norm}, {self.stylize}.")
        if self.style_code not in ("moments", "quantiles"):
            raise ValueError(f"style_code must be moments or quantiles, got {self.style_code}.")
        self.noise_scales = validate_noise_scales(self.noise_scales)
        self.noise_orientations = validate_noise_orientations(self.noise_orientations)
        if self.noise_per_scale < 1:
            raise ValueError(f"noise_per_scale must be >= 1, got {self.noise_per_scale}.")

    @property
    def code_size(self) -> int:
        return CODE_SIZE if self.style_code == "quantiles" else 0

    @property
    def noise_channels(self) -> int:
        return len(self.noise_orientations) * len(self.noise_scales) * self.noise_per_scale


class StyleInputs(NamedTuple):
    """What the SKPN reads of a batch of styles: the extractor's levels ``[(B, C_l, H_l, W_l)]`` and the
    quantile code ``(B, CODE_SIZE)`` (None for ``style_code="moments"``)."""

    levels: list
    code: torch.Tensor | None = None

    def repeat(self, times: int) -> StyleInputs:
        """Each style ``times`` times in a row, batch-wise (``[s0, s1, s0, s1]`` for two styles twice)."""
        return StyleInputs(
            [torch.cat([level] * times) for level in self.levels],
            None if self.code is None else torch.cat([self.code] * times),
        )


class StylizingKernels(NamedTuple):
    """The SKP's output for a batch of ``B`` styles: per kernel site, ``gamma`` and ``beta`` ``(B, C)``
    and, with ``stylize="kernel"``, ``weight (B, C, C, k, k, k)`` and ``bias (B, C)``."""

    sites: dict

    def without_noise(self) -> StylizingKernels:
        """These kernels with the noise site's weights at zero (``NOISE_SITE``; unchanged without one)."""
        if NOISE_SITE not in self.sites:
            return self
        weight = self.sites[NOISE_SITE]["weight"]
        return StylizingKernels({**self.sites, NOISE_SITE: {"weight": torch.zeros_like(weight)}})

    @staticmethod
    def blend(parts: list[tuple[StylizingKernels, float]]) -> StylizingKernels:
        """``sum_i w_i K_i`` over ``parts = [(K_i, w_i)]``, the weights normalised to sum 1 (each >= 0)."""
        weights = torch.tensor([float(w) for _, w in parts], dtype=torch.float64)
        if not parts or not torch.isfinite(weights).all() or (weights < 0).any() or weights.sum() <= 0:
            raise ValueError(f"Kernel blending needs finite weights >= 0 with a positive sum, got {weights.tolist()}.")
        weights = weights / weights.sum()
        first = parts[0][0].sites
        sites = {
            site: {
                key: sum(float(w) * kernels.sites[site][key] for (kernels, _), w in zip(parts, weights))
                for key in first[site]
            }
            for site in first
        }
        return StylizingKernels(sites)


class EncodedDensity(NamedTuple):
    """``SKPN.encode``'s output: the unpadded ``size (D, H, W)``, the encoder's three feature maps (full,
    1/2, 1/4 resolution of the grid padded to a multiple of 4), DAIN's density masks by resolution and
    the noise site's fields on the padded grid ``(1, C, D', H', W')`` (None without a noise site)."""

    size: tuple
    features: tuple
    masks: dict
    noise: torch.Tensor | None = None


class FoldedBody(NamedTuple):
    """``SKPN.fold_head_input``'s output: ``decode_body``'s features with a channel of ones appended
    ``(B, C + 1, D', H', W')``, and their mean ``(B, C)`` and covariance ``(B, C, C)`` as the last site's
    DAIN weighs voxels."""

    features: torch.Tensor
    mean: torch.Tensor
    covariance: torch.Tensor

    def in_bfloat16(self) -> FoldedBody:
        """The same with the features in bfloat16 (channels-last kept), for ``SKPN.folded_head_logits``
        in bfloat16; the moments stay float32."""
        return self._replace(features=self.features.to(torch.bfloat16))


NOISE_SITE = "noise"
"""The key of the noise site's kernel in ``StylizingKernels.sites``: ``{"weight": (B, 3, C)}``, how much of
each noise field each albedo channel's pre-tanh value gets."""


def site_key(text: str) -> int | str:
    """A kernel site's key from its name as a file stores it: a kernel site's number, or ``NOISE_SITE``."""
    return int(text) if str(text).isdigit() else str(text)


class NoiseWeightPredictor(nn.Module):
    """The noise site's predictor: three FC layers from the shallowest style level's (mean, std) and the
    style code to the ``(3, C)`` weights of the noise fields. The last layer starts at zero, so a network
    given a noise site computes exactly what it computed without one until training moves it."""

    def __init__(self, style_channels: int, channels: int, hidden: int, code_size: int = 0):
        super().__init__()
        self.channels = channels
        self.mlp = nn.Sequential(
            nn.Linear(2 * style_channels + code_size, hidden),
            nn.LeakyReLU(0.2),
            nn.Linear(hidden, hidden),
            nn.LeakyReLU(0.2),
            nn.Linear(hidden, 3 * channels),
        )
        nn.init.zeros_(self.mlp[-1].weight)
        nn.init.zeros_(self.mlp[-1].bias)

    def forward(self, style_level: torch.Tensor, code: torch.Tensor | None = None) -> dict:
        flat = style_level.flatten(2)
        statistics = [flat.mean(2), flat.std(2, unbiased=False)] + ([] if code is None else [code])
        return {"weight": self.mlp(torch.cat(statistics, dim=1)).view(-1, 3, self.channels)}


class StylizingKernelPredictor(nn.Module):
    """Three FC layers from one level's (mean, std), and the style code if any, to one stylizing kernel."""

    def __init__(
        self, style_channels: int, channels: int, hidden: int, kernel_size: int, with_kernel: bool, code_size: int = 0
    ):
        super().__init__()
        self.channels, self.kernel_size, self.with_kernel = channels, kernel_size, with_kernel
        outputs = (channels * channels * kernel_size**3 + channels if with_kernel else 0) + 2 * channels
        self.mlp = nn.Sequential(
            nn.Linear(2 * style_channels + code_size, hidden),
            nn.LeakyReLU(0.2),
            nn.Linear(hidden, hidden),
            nn.LeakyReLU(0.2),
            nn.Linear(hidden, outputs),
        )

    def forward(self, style_level: torch.Tensor, code: torch.Tensor | None = None) -> dict:
        flat = style_level.flatten(2)
        statistics = [flat.mean(2), flat.std(2, unbiased=False)] + ([] if code is None else [code])
        out = self.mlp(torch.cat(statistics, dim=1))
        c, k = self.channels, self.kernel_size
        result = {"gamma": 1.0 + out[:, :c], "beta": out[:, c : 2 * c]}
        if self.with_kernel:
            weights = out[:, 2 * c : 2 * c + c * c * k**3].view(-1, c, c, k, k, k)
            # Start near the identity so an untrained kernel passes features through.
            identity = torch.zeros_like(weights)
            identity[:, torch.arange(c), torch.arange(c), k // 2, k // 2, k // 2] = 1.0
            result["weight"] = identity + weights / (c * k**3) ** 0.5
            result["bias"] = out[:, 2 * c + c * c * k**3 :]
        return result


def _apply_kernel(x: torch.Tensor, kernel: dict) -> torch.Tensor:
    """Per-sample convolution of ``x (B, C, D, H, W)`` with ``weight (B, C, C, k, k, k)``.

    The predicted ``bias (B, C)`` is not added: it is a per-channel constant, which the (density-aware)
    instance normalisation that always follows removes exactly."""
    if "weight" not in kernel:
        return x
    batch, channels = x.shape[:2]
    weight = kernel["weight"]
    k = weight.shape[-1]
    if k == 1:
        y = torch.einsum("boi,bidhw->bodhw", weight[..., 0, 0, 0], x)
    else:
        y = F.conv3d(
            x.reshape(1, batch * channels, *x.shape[2:]),
            weight.reshape(batch * channels, channels, k, k, k),
            padding=k // 2,
            groups=batch,
        ).reshape(x.shape)
    return y


class _ResidualBlock(nn.Module):
    def __init__(self, channels: int):
        super().__init__()
        self.conv1 = nn.Conv3d(channels, channels, 3, padding=1)
        self.conv2 = nn.Conv3d(channels, channels, 3, padding=1)

    def forward(self, x):
        # In place on the convolutions' fresh outputs (their backward passes do not need them).
        return self.conv2(F.leaky_relu(self.conv1(x), 0.2, inplace=True)).add_(x)


class SKPN(nn.Module):
    def __init__(self, config: SKPNConfig | None = None):
        super().__init__()
        self.config = config = SKPNConfig() if config is None else config
        w0, w1, w2 = config.widths

        def block(cin, cout, stride):
            return nn.Sequential(
                nn.Conv3d(cin, cout, 3, stride=stride, padding=1),
                nn.LeakyReLU(0.2, inplace=True),
                *[_ResidualBlock(cout) for _ in range(config.residual_blocks)],
            )

        self.encoder = nn.ModuleList([block(1, w0, 1), block(w0, w1, 2), block(w1, w2, 2)])
        self.decoder = nn.ModuleList(
            [nn.Conv3d(w2 + w1, w1, 3, padding=1), nn.Conv3d(w1 + w0, w0, 3, padding=1), nn.Conv3d(w0, 3, 3, padding=1)]
        )
        # Kernel sites: bottleneck (w2), before decoder convs 1, 2, 3 (inputs w2 + w1 after the skip
        # are stylized on the upsampled part only, w2; then w1; then w0).
        site_channels = [w2, w2, w1, w0]
        active_sites = {1: [0], 2: [0, 3], 4: [0, 1, 2, 3]}[config.kernels]
        style_for_site = [3, 2, 1, 0]  # deepest style level at the bottleneck, then shallower
        with_kernel = config.stylize == "kernel"
        self.sites = active_sites
        self.predictors = nn.ModuleDict(
            {
                str(site): StylizingKernelPredictor(
                    config.style_channels[style_for_site[site]],
                    site_channels[site],
                    config.style_hidden,
                    config.kernel_size,
                    with_kernel,
                    config.code_size,
                )
                for site in active_sites
            }
        )
        self.style_for_site = style_for_site
        if config.noise_channels:
            self.noise_predictor = NoiseWeightPredictor(
                config.style_channels[0], config.noise_channels, config.style_hidden, config.code_size
            )

    @torch.no_grad()
    def encode_style(self, images: torch.Tensor, extractor: nn.Module) -> StyleInputs:
        """``StyleInputs`` of style images ``(B, 3, S, S)`` in display [0, 1], with ``extractor``'s levels."""
        levels = list(extractor(images))
        return StyleInputs(levels, style_code(images) if self.config.style_code == "quantiles" else None)

    def predict_kernels(self, style: StyleInputs | list[torch.Tensor]) -> StylizingKernels:
        """The SKP: ``StylizingKernels`` of ``encode_style``'s output (or, for ``style_code="moments"``,
        the bare list of levels)."""
        if not isinstance(style, StyleInputs):
            style = StyleInputs(list(style))
        if (style.code is None) != (self.config.style_code == "moments"):
            raise ValueError(
                f"this SKPN has style_code={self.config.style_code!r}; build its style input with encode_style."
            )
        sites = {
            site: self.predictors[str(site)](style.levels[self.style_for_site[site]], style.code) for site in self.sites
        }
        if self.config.noise_channels:
            sites[NOISE_SITE] = self.noise_predictor(style.levels[0], style.code)
        return StylizingKernels(sites)

    @torch.no_grad()
    def neutral_kernels(self, kernels: StylizingKernels, grey: float) -> StylizingKernels:
        """``kernels`` with the last site's replaced so that the albedo is ``grey`` everywhere.

        With ``gamma = 0`` DAIN outputs ``beta``: the features entering the last convolution are a
        constant, which that convolution (weights summed over its 3^3 taps) and the tanh map to one
        albedo; ``beta`` is the least-norm solution giving ``grey`` in every channel. Exact away
        from the grid's faces, where the convolution's zero padding enters (empty space in practice).
        Blending towards these kernels (``StylizingKernels.blend``) moves the albedo's pre-tanh
        values linearly from the style's to the grey's: the style strength."""
        last = max(self.sites)
        if last != 3:
            raise ValueError(
                "Style strength needs an SKPN with a kernel before its last convolution (model.kernels = 2 "
                "or 4); this checkpoint has none. Use strength 1 or another checkpoint."
            )
        conv = self.decoder[2]
        taps = conv.weight.sum(dim=(2, 3, 4)).double()  # (3, C): the convolution of a constant field
        level = min(max(float(grey), 1e-3), 1.0 - 1e-3)
        target = torch.full((3,), 2.0 * level - 1.0, dtype=torch.float64).atanh() - conv.bias.double()
        beta = torch.linalg.pinv(taps) @ target
        site = dict(kernels.sites[last])
        site["gamma"] = torch.zeros_like(site["gamma"])
        site["beta"] = beta.to(site["beta"]).expand_as(site["beta"]).clone()
        return StylizingKernels({**kernels.sites, last: site}).without_noise()  # grey everywhere: no noise either

    def forward(
        self,
        density: torch.Tensor,
        style: StyleInputs | StylizingKernels | list[torch.Tensor],
        noise: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """Albedo ``(B, 3, D, H, W)`` of ``density (B, 1, D, H, W)``; ``style``: ``encode_style``'s output
        (or, for ``style_code="moments"``, the bare list of levels), or kernels from ``predict_kernels``.
        ``noise``: the noise site's fields over this grid (``encode``)."""
        kernels = style if isinstance(style, StylizingKernels) else self.predict_kernels(style)
        return self.decode(self.encode(density, noise), kernels)

    def noise_fields(self, size: tuple, window: tuple[slice, slice, slice] | None = None) -> torch.Tensor | None:
        """The noise site's fields ``(1, C, D, H, W)`` of a grid of ``size (D, H, W)``, on the network's
        device, cut to ``window`` (``occupied_window``) when given; None without a noise site."""
        config = self.config
        if not config.noise_channels:
            return None
        fields = noise_fields(
            size, config.noise_scales, config.noise_per_scale, config.noise_seed, config.noise_orientations, window
        )
        return fields[None].to(next(self.parameters()).device)

    def encode(
        self, density: torch.Tensor, noise: torch.Tensor | None = None, noise_site: bool = True
    ) -> EncodedDensity:
        """The encoder's half of ``forward``: what ``decode`` needs of ``density (B, 1, D, H, W)``, which
        does not depend on the style (so a look's fit computes it once per key frame). ``noise``: the
        noise site's fields ``(1, C, D, H, W)`` for this grid (a crop passes its part of the whole grid's,
        ``noise_fields``); default: the fields of a grid of the density's size. ``noise_site=False``:
        none, for kernels whose noise weights are zero (``StylizingKernels.without_noise``, a look's),
        which would add nothing to the logits."""
        if density.dim() != 5 or density.shape[1] != 1:
            raise ValueError(f"density must be (B, 1, D, H, W), got {tuple(density.shape)}.")
        size = tuple(density.shape[2:])
        pads = [p for n in reversed(size) for p in (0, (-n) % 4)]
        padded = F.pad(density, pads)
        e0 = self.encoder[0](padded)
        e1 = self.encoder[1](e0)
        e2 = self.encoder[2](e1)
        masks = {}
        if self.config.norm == "dain":
            masks = {tuple(e.shape[2:]): density_mask(padded, e.shape[2:]) for e in (e0, e1, e2)}
        if self.config.noise_channels and noise_site:
            noise = self.noise_fields(size) if noise is None else noise
            if tuple(noise.shape[2:]) != size or noise.shape[1] != self.config.noise_channels:
                expected = (1, self.config.noise_channels, *size)
                raise ValueError(f"noise must be {expected} for this density, got {tuple(noise.shape)}.")
            noise = F.pad(noise.float(), pads)
        else:
            noise = None
        return EncodedDensity(size, (e0, e1, e2), masks, noise)

    def decode(self, encoded: EncodedDensity, kernels: StylizingKernels) -> torch.Tensor:
        """The stylized decoder's half of ``forward``: albedo ``(B, 3, D, H, W)``."""
        return self.decode_head(self.decode_body(encoded, kernels), kernels, encoded)

    def _stylize(self, x: torch.Tensor, site: int, kernels: StylizingKernels, encoded: EncodedDensity) -> torch.Tensor:
        if site not in kernels.sites:
            return x
        kernel = kernels.sites[site]
        mask = encoded.masks.get(tuple(x.shape[2:])) if self.config.norm == "dain" else None
        return dain(_apply_kernel(x, kernel), mask, kernel["gamma"], kernel["beta"])

    def decode_body(self, encoded: EncodedDensity, kernels: StylizingKernels) -> torch.Tensor:
        """The decoder up to its last kernel site: full-resolution features ``(B, w0, D', H', W')``
        (``decode_head`` finishes them; a fit that tunes only the head computes these once)."""
        e0, e1, e2 = encoded.features
        x = self._stylize(e2, 0, kernels, encoded)
        x = self._stylize(F.interpolate(x, scale_factor=2, mode="trilinear", align_corners=False), 1, kernels, encoded)
        x = F.relu(self.decoder[0](torch.cat([x, e1], dim=1)), inplace=True)
        x = self._stylize(F.interpolate(x, scale_factor=2, mode="trilinear", align_corners=False), 2, kernels, encoded)
        return F.relu(self.decoder[1](torch.cat([x, e0], dim=1)), inplace=True)

    def decode_head(
        self, x: torch.Tensor, kernels: StylizingKernels, encoded: EncodedDensity, offset: torch.Tensor | None = None
    ) -> torch.Tensor:
        """The last kernel site and convolution on ``decode_body``'s features: albedo ``(B, 3, D, H, W)``.
        ``offset`` (broadcast to ``(B, 3, D', H', W')``, the padded grid) is added before the tanh (a look's
        noise term)."""
        logits = self.head_logits(self.head_site(x, kernels, encoded), kernels, encoded)
        return head_albedo(logits if offset is None else logits + offset, encoded.size)

    def head_site(self, x: torch.Tensor, kernels: StylizingKernels, encoded: EncodedDensity) -> torch.Tensor:
        """The last kernel site on ``decode_body``'s features (a fit that tunes only the last
        convolution computes this once)."""
        return self._stylize(x, 3, kernels, encoded)

    def head_logits(self, x: torch.Tensor, kernels: StylizingKernels, encoded: EncodedDensity) -> torch.Tensor:
        """The last convolution and the noise site on ``head_site``'s features: the albedo's logits
        ``(B, 3, D', H', W')`` on the padded grid, before the tanh (a fit that tunes only what it adds to
        them computes these once)."""
        return self._add_noise(self.decoder[2](x).float(), kernels, encoded)

    def _add_noise(self, logits: torch.Tensor, kernels: StylizingKernels, encoded: EncodedDensity) -> torch.Tensor:
        if NOISE_SITE in kernels.sites and encoded.noise is not None:
            weight = kernels.sites[NOISE_SITE]["weight"].float()
            noise = encoded.noise.expand(weight.shape[0], *encoded.noise.shape[1:])
            logits = logits + torch.einsum("boc,bcdhw->bodhw", weight, noise)
        return logits

    def fold_head_input(self, x: torch.Tensor, encoded: EncodedDensity) -> FoldedBody | None:
        """What ``folded_head_logits`` needs of ``decode_body``'s features ``x``; None where the last
        site's DAIN mask is empty (the plain path then applies)."""
        mask = encoded.masks.get(tuple(x.shape[2:])) if self.config.norm == "dain" else None
        if mask is not None and not bool((mask.flatten(1).sum(1) > 1e-12).all()):
            return None
        mean, covariance = masked_moments(x, mask)
        inside = torch.ones((x.shape[0], 1, *x.shape[2:]), dtype=torch.float32, device=x.device)
        # Channels-last: the one convolution a fit step runs is about 1.7x faster in it on this project's CPU.
        features = torch.cat([x.float(), inside], dim=1).contiguous(memory_format=torch.channels_last_3d)
        return FoldedBody(features, mean, covariance)

    @staticmethod
    def folds_head(kernels: StylizingKernels) -> bool:
        """Whether ``folded_head_logits`` applies: the last site's kernel is a 1x1x1 channel mix."""
        weight = kernels.sites.get(3, {}).get("weight")
        return weight is not None and tuple(weight.shape[-3:]) == (1, 1, 1)

    def folded_head_weight(self, body: FoldedBody, kernels: StylizingKernels) -> torch.Tensor:
        """The weights ``(B, O, C + 1, k, k, k)`` of the one convolution of ``folded_head_logits`` (its bias
        is the last convolution's)."""
        kernel = kernels.sites[3]
        scale, shift = dain_of_mixed(
            body.mean, body.covariance, kernel["weight"][..., 0, 0, 0].float(), kernel["gamma"], kernel["beta"]
        )
        convolution = self.decoder[2]
        return torch.cat(
            [
                torch.einsum("oc...,bci->boi...", convolution.weight, scale),
                torch.einsum("oc...,bc->bo...", convolution.weight, shift)[:, :, None],
            ],
            dim=2,
        )

    def folded_head_logits(self, body: FoldedBody, kernels: StylizingKernels, encoded: EncodedDensity) -> torch.Tensor:
        """``head_logits(head_site(x, ...), ...)`` as one convolution of ``body = fold_head_input(x, ...)``.

        The last site (a 1x1x1 mix, then DAIN, whose statistics follow from the features' moments) is an
        affine map of ``x`` (``dain_of_mixed``); its matrix folds into the last convolution's weights, its
        shift into the weights of the input's channel of ones (zero outside the grid, as the plain path
        pads). Equal to the plain path up to rounding; a fit that holds ``x`` fixed and tunes the kernel or
        the convolution steps about twice as fast, as nothing of ``x``'s size needs a gradient.

        ``body.features`` in bfloat16 (``FoldedBody.in_bfloat16``) run the convolution in bfloat16, its
        weights cast to it; the logits are float32 either way."""
        convolution = self.decoder[2]
        features = body.features
        batch, channels = features.shape[:2]
        weight = self.folded_head_weight(body, kernels).to(features.dtype)
        bias = convolution.bias.to(features.dtype)
        if batch == 1:
            logits = F.conv3d(features, weight[0].contiguous(), bias, padding=convolution.padding)
        else:
            logits = F.conv3d(
                features.reshape(1, batch * channels, *features.shape[2:]),
                weight.reshape(-1, channels, *weight.shape[3:]),
                bias.repeat(batch),
                padding=convolution.padding,
                groups=batch,
            ).reshape(batch, -1, *features.shape[2:])
        return self._add_noise(logits.float(), kernels, encoded)

    @torch.no_grad()
    def infer(
        self,
        density: torch.Tensor,
        style: StyleInputs | StylizingKernels | list[torch.Tensor],
        precision: str | None = None,
        crop_margin: int | None = DEFAULT_CROP_MARGIN,
    ) -> torch.Tensor:
        """``forward`` for inference, faster: in ``precision`` (``"bf16"``: bfloat16 autocast, as the
        network was trained; ``"fp32"``: plain; None: ``inference_precision`` of the device), and with
        ``crop_margin`` set, only over the bounding box of the density's voxels above ``OCCUPIED_DENSITY``
        grown by that many voxels (its low corner on a multiple of 4, so the strided levels keep their
        alignment). Outside the box the albedo repeats its faces' values: there is no medium there to show
        it. Returns float32 ``(B, 3, D, H, W)``.

        Both change the albedo slightly against ``forward`` in float32 over the whole box (bfloat16
        rounding; the convolutions near the crop see zero padding instead of empty-space features);
        ``experiments/bench_skpn.py`` measures the change and ``tests/test_skpn.py`` bounds it."""
        precision = inference_precision(density.device) if precision is None else precision
        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {PRECISIONS}, got {precision!r}.")
        window = occupied_window(density, crop_margin) if crop_margin is not None else None
        part = density if window is None else density[(..., *window)]
        kernels = style if isinstance(style, StylizingKernels) else self.predict_kernels(style)  # float32: cheap
        noise = self.noise_fields(tuple(density.shape[2:]), window)  # the whole grid's fields, cut as the density
        with torch.autocast(density.device.type, dtype=torch.bfloat16, enabled=precision == "bf16"):
            albedo = self(part, kernels, noise).float()
        return uncrop(albedo, window, density.shape[2:])


def head_albedo(logits: torch.Tensor, size: tuple) -> torch.Tensor:
    """Albedo in [0, 1] of the head's logits ``(B, 3, D', H', W')`` on the padded grid, cut to ``size``."""
    albedo = 0.5 * (torch.tanh(logits) + 1.0)
    return albedo[..., : size[0], : size[1], : size[2]]


def inference_precision(device: torch.device) -> str:
    """``"bf16"`` where the hardware computes bfloat16 natively (CUDA; CPUs with AVX-512 BF16 or AMX, as
    oneDNN reports), else ``"fp32"``: elsewhere bfloat16 convolutions are emulated, about 200x slower
    than float32 at 64^3 on an AMD EPYC without AVX-512 BF16 (``SKPN.infer`` with either ``precision``)."""
    if torch.device(device).type == "cuda":
        return "bf16"
    return "bf16" if torch.backends.mkldnn.is_available() and torch.ops.mkldnn._is_mkldnn_bf16_supported() else "fp32"


def occupied_window(density: torch.Tensor, margin: int) -> tuple[slice, slice, slice] | None:
    """The (D, H, W) slices of the bounding box of ``density (B, 1, D, H, W)``'s voxels above
    ``OCCUPIED_DENSITY`` grown by ``margin``, the low corner rounded down to a multiple of 4; None when
    that is the whole grid or no voxel is above it."""
    occupied = (density > OCCUPIED_DENSITY).flatten(0, 1).any(dim=0)
    if not occupied.any():
        return None
    window = []
    for axis in range(3):
        present = torch.nonzero(occupied.any(dim=tuple(a for a in range(3) if a != axis))).flatten()
        low = max(int(present[0]) - margin, 0) // 4 * 4
        high = min(int(present[-1]) + 1 + margin, occupied.shape[axis])
        window.append(slice(low, high))
    return None if all(w.start == 0 and w.stop == n for w, n in zip(window, occupied.shape)) else tuple(window)


def uncrop(albedo: torch.Tensor, window: tuple[slice, slice, slice] | None, size) -> torch.Tensor:
    """``albedo`` computed over ``window`` of a grid of ``size (D, H, W)`` (``occupied_window``) back on the
    whole grid, its faces' values repeated outside the window (where there is no medium to show them)."""
    if window is None:
        return albedo
    pads = [p for w, n in reversed(list(zip(window, size))) for p in (w.start, n - w.stop)]
    return F.pad(albedo, pads, mode="replicate")


def parameter_count(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
