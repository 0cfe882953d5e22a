"""Feature extractors: four feature levels of an image batch, for the style losses and the SKP.

Every extractor maps images ``(B, 3, H, W)`` in display space [0, 1] to four feature maps
``[(B, C_1, H, W), (B, C_2, H/2, W/2), (B, C_3, H/4, W/4), (B, C_4, H/8, W/8)]``.

* ``VGG16Features``: VGG16's ``features`` up to relu4_3, in torchvision's layout and state-dict key
  names (``features.0.weight`` ...), ImageNet-normalised input; levels relu1_2, relu2_2, relu3_3,
  relu4_3. Pretrained weights are loaded from a file the user gives (``--vgg-weights``, the
  ``MISTYLE_VGG16_WEIGHTS`` environment variable, or torch hub's cache
  ``checkpoints/vgg16-397923af.pth``); nothing is downloaded. The same network with fixed random
  weights (``random_vgg16``) is one offline candidate.
* ``FilterBankFeatures``: a fixed multi-scale filter bank, in the spirit of Heeger-Bergen texture
  synthesis: at each level of a Gaussian pyramid, the colour channels, their oriented first
  derivatives at four angles, and a centre-surround (Laplacian) response, rectified into positive
  and negative parts. No weights at all.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from ..conventions import EXTRACTOR_KINDS, OFFLINE_EXTRACTOR

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)
VGG16_FILE = "vgg16-397923af.pth"
# (in, out) of each conv up to relu4_3; "M" is a 2x2 max pool.
_VGG16_PLAN = [
    (3, 64),
    (64, 64),
    "M",
    (64, 128),
    (128, 128),
    "M",
    (128, 256),
    (256, 256),
    (256, 256),
    "M",
    (256, 512),
    (512, 512),
    (512, 512),
]
_VGG16_TAPS = (3, 8, 15, 22)  # indices of relu1_2, relu2_2, relu3_3, relu4_3 in torchvision's features


class VGG16Features(nn.Module):
    """VGG16 ``features[0:23]`` with torchvision's module indices; returns relu1_2 ... relu4_3."""

    levels = ("relu1_2", "relu2_2", "relu3_3", "relu4_3")
    channels = (64, 128, 256, 512)

    def __init__(self, name: str = "vgg16"):
        super().__init__()
        layers: list[nn.Module] = []
        for entry in _VGG16_PLAN:
            if entry == "M":
                layers.append(nn.MaxPool2d(2, 2))
            else:
                layers += [nn.Conv2d(entry[0], entry[1], 3, padding=1), nn.ReLU(inplace=False)]
        self.features = nn.Sequential(*layers)
        self.register_buffer("mean", torch.tensor(IMAGENET_MEAN).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor(IMAGENET_STD).view(1, 3, 1, 1))
        self.name = name
        for parameter in self.parameters():
            parameter.requires_grad_(False)

    def forward(self, images: torch.Tensor) -> list[torch.Tensor]:
        x = (images - self.mean) / self.std
        outputs = []
        for index, layer in enumerate(self.features):
            x = layer(x)
            if index in _VGG16_TAPS:
                outputs.append(x)
        return outputs

    def load_torchvision_state_dict(self, state_dict: dict, source: str = "state dict") -> None:
        """Load torchvision VGG16 weights (``features.*`` keys; ``classifier.*`` and deeper layers ignored)."""
        wanted = {
            key: value
            for key, value in state_dict.items()
            if key.startswith("features.") and int(key.split(".")[1]) < len(self.features)
        }
        expected = {key for key in self.state_dict() if key.startswith("features.")}
        missing = sorted(expected - wanted.keys())
        if missing:
            raise ValueError(f"{source} is not a torchvision VGG16 state dict: missing {missing[:4]}...")
        for key, value in wanted.items():
            if tuple(value.shape) != tuple(self.state_dict()[key].shape):
                raise ValueError(
                    f"{source}: {key} has shape {tuple(value.shape)}, "
                    f"VGG16 needs {tuple(self.state_dict()[key].shape)}."
                )
        self.load_state_dict(wanted, strict=False)


def random_vgg16(seed: int = 0) -> VGG16Features:
    """VGG16 with fixed random weights (Kaiming-normal convolutions, zero biases)."""
    model = VGG16Features(name=f"vgg16-random-seed{seed}")
    generator = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for module in model.features:
            if isinstance(module, nn.Conv2d):
                fan_in = module.in_channels * 9
                module.weight.copy_(torch.randn(module.weight.shape, generator=generator) * math.sqrt(2.0 / fan_in))
                module.bias.zero_()
    return model


class FilterBankFeatures(nn.Module):
    """Fixed oriented multi-scale filters on colour; see the module docstring."""

    levels = ("bank_1", "bank_2", "bank_3", "bank_4")
    angles = 4

    def __init__(self):
        super().__init__()
        self.name = "filterbank"
        x = torch.arange(-3, 4, dtype=torch.float32)
        yy, xx = torch.meshgrid(x, x, indexing="ij")
        gauss = torch.exp(-(xx**2 + yy**2) / (2 * 1.2**2))
        kernels = []
        for k in range(self.angles):  # oriented derivatives of a Gaussian
            theta = math.pi * k / self.angles
            kernel = -(math.cos(theta) * xx + math.sin(theta) * yy) * gauss
            kernels.append(kernel / kernel.abs().sum())
        surround = torch.exp(-(xx**2 + yy**2) / (2 * 2.4**2))
        dog = gauss / gauss.sum() - surround / surround.sum()
        kernels.append(dog / dog.abs().sum() * 2)
        bank = torch.stack(kernels)[:, None]  # (5, 1, 7, 7)
        self.register_buffer("bank", bank)
        blur = torch.tensor([1.0, 4.0, 6.0, 4.0, 1.0])
        self.register_buffer("blur", (blur[:, None] * blur[None, :] / 256.0)[None, None])
        per_channel = 3 + 3 * 2 * (self.angles + 1)
        self.channels = (per_channel,) * 4

    def forward(self, images: torch.Tensor) -> list[torch.Tensor]:
        outputs, x = [], images
        for level in range(4):
            if level:
                x = F.conv2d(F.pad(x, (2, 2, 2, 2), mode="replicate"), self.blur.expand(3, 1, 5, 5), groups=3)[
                    ..., ::2, ::2
                ]
            responses = F.conv2d(F.pad(x, (3, 3, 3, 3), mode="replicate"), self.bank.repeat(3, 1, 1, 1), groups=3)
            outputs.append(torch.cat([x, F.relu(responses), F.relu(-responses)], dim=1))
        return outputs


def vgg16_weights_path(explicit: str | os.PathLike | None = None) -> Path | None:
    """Where VGG16 ImageNet weights are: the explicit path, ``$MISTYLE_VGG16_WEIGHTS``, or torch hub's cache."""
    if explicit:
        path = Path(explicit)
        if not path.is_file():
            raise ValueError(f"VGG16 weights file {path} does not exist.")
        return path
    from_env = os.environ.get("MISTYLE_VGG16_WEIGHTS")
    if from_env:
        path = Path(from_env)
        if not path.is_file():
            raise ValueError(f"MISTYLE_VGG16_WEIGHTS points to {path}, which does not exist.")
        return path
    hub = Path(torch.hub.get_dir()) / "checkpoints" / VGG16_FILE
    return hub if hub.is_file() else None


def make_extractor(kind: str = "auto", weights: str | os.PathLike | None = None) -> nn.Module:
    """``auto``: VGG16-ImageNet when weights are found, else the offline default; or name one:
    ``vgg16`` (needs weights), ``vgg16-random``, ``filterbank``."""
    if kind not in EXTRACTOR_KINDS:
        raise ValueError(f"Unknown feature extractor {kind!r}: use one of {', '.join(EXTRACTOR_KINDS)}.")
    if kind in ("auto", "vgg16"):
        path = vgg16_weights_path(weights)
        if path is not None:
            return _imagenet_vgg16(path)
        if kind == "vgg16":
            raise ValueError(
                "VGG16 ImageNet weights were not found: pass --vgg-weights FILE, set MISTYLE_VGG16_WEIGHTS, or put "
                f"{VGG16_FILE} in {Path(torch.hub.get_dir()) / 'checkpoints'}."
            )
        kind = OFFLINE_EXTRACTOR
    if kind == "vgg16-random":
        return random_vgg16().eval()
    return FilterBankFeatures().eval()


def extractor_from_name(name: str, weights: str | os.PathLike | None = None) -> nn.Module:
    """The extractor whose ``.name`` is ``name``, as a checkpoint records it.

    ``vgg16-imagenet`` (needs the weights, as for ``make_extractor("vgg16")``),
    ``vgg16-random-seed<N>`` or ``filterbank``.
    """
    if name == "vgg16-imagenet":
        return make_extractor("vgg16", weights)
    if name == "filterbank":
        return FilterBankFeatures().eval()
    seeded = re.fullmatch(r"vgg16-random-seed(\d+)", name)
    if seeded:
        return random_vgg16(int(seeded.group(1))).eval()
    raise ValueError(
        f"Unknown feature extractor {name!r}; this mistyle knows vgg16-imagenet, vgg16-random-seed<N> and filterbank."
    )


def _imagenet_vgg16(path: Path) -> VGG16Features:
    model = VGG16Features(name="vgg16-imagenet")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # a corrupt or foreign file; never advise weights_only=False for it
        raise ValueError(f"Cannot read VGG16 weights from {path}: {type(error).__name__}.") from None
    model.load_torchvision_state_dict(state, source=str(path))
    return model.eval()


def square_style(image: np.ndarray, size: int) -> torch.Tensor:
    """Centre-crop an ``(H, W, 3)`` image to a square and resize it to ``(3, size, size)`` (antialiased)."""
    tensor = torch.from_numpy(np.ascontiguousarray(image, dtype=np.float32)).permute(2, 0, 1)
    height, width = tensor.shape[1:]
    side = min(height, width)
    top, left = (height - side) // 2, (width - side) // 2
    tensor = tensor[:, top : top + side, left : left + side]
    if side != size:
        tensor = F.interpolate(tensor[None], size=(size, size), mode="bilinear", antialias=True, align_corners=False)[0]
    return tensor.clamp(0, 1).contiguous()
