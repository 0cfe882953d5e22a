"""Checkpoints: the one reader and writer of SKPN checkpoint files, for training and inference.

A checkpoint is a ``dict`` saved with ``torch.save`` and read with ``weights_only=True`` (no pickle
code ever runs): ``format``, ``mistyle_version``, ``step``, ``seconds``, ``config``
(``config_to_dict``), ``extractor`` (the feature extractor's ``name``), ``density_scale`` and
``model`` (the state dict); training checkpoints add ``optimizer``, ``scheduler``, ``rng`` and
``world_size``, which ``export_checkpoint`` strips for inference.

Loading checks what it can of the bytes: every tensor finite, the model's weights a dict of tensors,
and, in checkpoints that carry it, ``tensors_sha256`` (a digest of every tensor, written by
``save_checkpoint``) unchanged, so a damaged file is named as such rather than blamed on what it
stylizes. The weights' shapes are checked against the network by ``load_state_dict`` where it is built.
"""

from __future__ import annotations

import hashlib
import warnings
from dataclasses import dataclass
from pathlib import Path

import torch
import torch.nn as nn

from ..conventions import DEFAULT_DENSITY_SCALE
from ..files import atomic_output
from ..scenes.medium import validate_density_scale
from .config import TrainConfig, apply_overrides, config_from_dict, config_to_dict
from .features import extractor_from_name
from .skpn import SKPN

CHECKPOINT_FORMAT = 1
INFERENCE_KEYS = (
    "format",
    "mistyle_version",
    "step",
    "seconds",
    "config",
    "extractor",
    "density_scale",
    "model",
    "averaged_from",
    "recipe",
)
DIGEST_KEY = "tensors_sha256"


def load_checkpoint(path) -> dict:
    """Read a checkpoint; ``ValueError`` naming the file and the problem for a missing, damaged or foreign file."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"No checkpoint file at {path}.")
    with open(path, "rb") as handle:
        if handle.read(4) != b"PK\x03\x04":  # torch's archives are zip files
            raise ValueError(
                f"{path} is not a mistyle checkpoint (not a file torch.save writes); only checkpoints written "
                "by mistyle can be loaded."
            )
    try:
        with warnings.catch_warnings():  # torch warns about foreign pickle protocols; the error below says it all
            warnings.simplefilter("ignore")
            checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # torch raises many kinds for a damaged or unsafe file
        # torch's own message advises weights_only=False; never pass that advice on for a foreign file.
        raise ValueError(
            f"{path} is not a readable mistyle checkpoint ({type(error).__name__}); "
            "only checkpoints written by mistyle can be loaded."
        ) from None
    if not isinstance(checkpoint, dict) or checkpoint.get("format") != CHECKPOINT_FORMAT or "model" not in checkpoint:
        raise ValueError(f"{path} is not a mistyle SKPN checkpoint (format {CHECKPOINT_FORMAT}).")
    check_tensors(checkpoint, path)
    return checkpoint


def _tensors(value, where: str = ""):
    """``(where, tensor)`` for every tensor in a checkpoint's nested dicts and lists, in a fixed order."""
    if isinstance(value, torch.Tensor):
        yield where, value
    elif isinstance(value, dict):
        for key in sorted(value, key=str):
            if key != DIGEST_KEY:
                yield from _tensors(value[key], f"{where}/{key}")
    elif isinstance(value, (list, tuple)):
        for index, item in enumerate(value):
            yield from _tensors(item, f"{where}/{index}")


def tensors_digest(checkpoint: dict) -> str:
    """SHA-256 of every tensor of ``checkpoint`` (names, dtypes, shapes and bytes)."""
    digest = hashlib.sha256()
    for where, tensor in _tensors(checkpoint):
        digest.update(f"{where}:{tensor.dtype}:{tuple(tensor.shape)};".encode())
        digest.update(tensor.detach().cpu().contiguous().view(-1).view(torch.uint8).numpy().tobytes())
    return digest.hexdigest()


def check_tensors(checkpoint: dict, path) -> None:
    """``ValueError`` naming ``path`` unless the weights are a dict of tensors, every floating tensor is
    finite, and the digest (where the file has one) matches its tensors."""
    fix = "use another checkpoint (e.g. an earlier steps/step_*.pt of the run), or train it again"
    model = checkpoint["model"]
    if not isinstance(model, dict) or not all(isinstance(v, torch.Tensor) for v in model.values()):
        raise ValueError(f"{path}: its model weights are not a dict of tensors; {fix}.")
    expected = checkpoint.get(DIGEST_KEY)
    if expected is not None and tensors_digest(checkpoint) != expected:
        raise ValueError(f"{path} is damaged: its tensors no longer match the SHA-256 written with them; {fix}.")
    for where, tensor in _tensors(checkpoint):
        if tensor.is_floating_point() and not bool(torch.isfinite(tensor).all()):
            why = "the file is intact: the run that wrote it diverged" if expected else "damaged, or its run diverged"
            raise ValueError(f"{path}: {where.lstrip('/')} holds NaN or inf values ({why}); {fix}.")


def save_checkpoint(path, payload: dict) -> Path:
    """Write ``payload`` (see the module docstring) atomically, with the digest of its tensors."""
    payload = {**payload, DIGEST_KEY: tensors_digest(payload)}
    with atomic_output(path) as tmp:
        torch.save(payload, tmp)
    return Path(path)


def build_model(config: TrainConfig, extractor: nn.Module) -> SKPN:
    """SKPN for ``config.model`` with the style widths of ``extractor`` (written into the config)."""
    config.model.style_channels = tuple(int(c) for c in extractor.channels)
    return SKPN(config.model)


def model_from_checkpoint(checkpoint: dict, path) -> tuple[SKPN, TrainConfig]:
    """The network of a checkpoint read by ``load_checkpoint`` (eval mode, CPU) and its config."""
    try:
        config = config_from_dict(checkpoint["config"], where=str(path))
        model = SKPN(config.model)
        model.load_state_dict(checkpoint["model"])
    except (KeyError, RuntimeError, ValueError) as error:
        raise ValueError(
            f"{path} does not match this version's SKPN ({type(error).__name__}: {error}); "
            "retrain, or use the mistyle version that wrote it "
            f"({checkpoint.get('mistyle_version', 'unknown')})."
        ) from None
    return model.eval(), config


@dataclass
class TrainedModel:
    """Everything inference needs from a checkpoint."""

    path: Path
    model: SKPN  # eval mode
    config: TrainConfig  # as trained: style size, light, orbit, objective
    extractor: nn.Module  # the feature extractor the network's style code was trained on
    density_scale: float  # extinction per unit density of the training data


def load_model(path, vgg_weights=None) -> TrainedModel:
    """Load a checkpoint for inference, with the feature extractor it names; ``ValueError`` if unusable."""
    path = Path(path)
    checkpoint = load_checkpoint(path)
    model, config = model_from_checkpoint(checkpoint, path)
    name = checkpoint.get("extractor")
    try:
        extractor = extractor_from_name(str(name), vgg_weights)
    except ValueError as error:
        raise ValueError(f"{path} was trained with the feature extractor {name!r}: {error}") from None
    if tuple(extractor.channels) != tuple(config.model.style_channels):
        raise ValueError(
            f"{path} expects style features of widths {config.model.style_channels}, "
            f"the {extractor.name} extractor gives {extractor.channels}."
        )
    density_scale = validate_density_scale(
        checkpoint.get("density_scale", DEFAULT_DENSITY_SCALE), f"{path}: density_scale"
    )
    return TrainedModel(path, model, config, extractor, density_scale)


def export_checkpoint(source, destination, overrides: list[str] = (), half: bool = False) -> Path:
    """An inference checkpoint: the weights, config, extractor and provenance of a training checkpoint,
    without the optimizer state (a third of the size). ``load_model`` and ``mistyle.stylize`` read it.

    ``overrides``: ``section.key=value`` changes to the stored config, for settings that leave the
    network's weights as they are; a change that no longer fits the weights is a ``ValueError``.
    ``half``: store the weights as float16 (half the size; they load back into the float32 network)."""
    checkpoint = load_checkpoint(source)
    payload = {key: checkpoint[key] for key in INFERENCE_KEYS if key in checkpoint}
    payload.setdefault("density_scale", DEFAULT_DENSITY_SCALE)
    if overrides:
        config = apply_overrides(config_from_dict(checkpoint["config"], where=str(source)), list(overrides))
        payload["config"] = config_to_dict(config)
        try:
            SKPN(config.model).load_state_dict(payload["model"])
        except RuntimeError:
            raise ValueError(
                f"--set {' '.join(overrides)} changes the network {source} holds (its weights no longer fit); "
                "an export may change only settings that leave the weights as they are."
            ) from None
    if half:
        payload["model"] = {
            key: value.half() if value.is_floating_point() else value for key, value in payload["model"].items()
        }
    return save_checkpoint(destination, payload)


def average_checkpoints(sources, destination) -> Path:
    """An inference checkpoint whose weights are the mean of ``sources``' (stochastic weight averaging of
    checkpoints along one run); config, extractor and step are the last source's. ``ValueError`` when
    the sources differ in architecture or extractor."""
    checkpoints = [load_checkpoint(source) for source in sources]
    last = checkpoints[-1]
    for source, checkpoint in zip(sources, checkpoints):
        if (
            checkpoint.get("extractor") != last.get("extractor")
            or checkpoint["model"].keys() != last["model"].keys()
            or any(value.shape != last["model"][key].shape for key, value in checkpoint["model"].items())
        ):
            raise ValueError(
                f"{source} does not share the architecture and extractor of {sources[-1]}; "
                "average checkpoints of one run only."
            )
    payload = {key: last[key] for key in INFERENCE_KEYS if key in last}
    payload["model"] = {
        key: sum(checkpoint["model"][key].float() for checkpoint in checkpoints) / len(checkpoints)
        for key in last["model"]
    }
    payload["averaged_from"] = [
        f"{Path(source).name} (step {checkpoint.get('step')})" for source, checkpoint in zip(sources, checkpoints)
    ]
    payload.setdefault("density_scale", DEFAULT_DENSITY_SCALE)
    return save_checkpoint(destination, payload)
