"""A model's configuration: how it is built, trained and meant to be rendered, as nested dataclasses.

Read from TOML and ``--set section.key=value`` by ``python -m mistyle.train``, stored in every
checkpoint, and read back from there by inference (the style size, the light and the orbit a
network was trained with). Every key has a type; a key the dataclasses do not name, or a value of the wrong type, is a
``ConfigError`` that says which key and what was expected, before any work starts. The resolved
config is written next to a run's outputs and stored in each checkpoint.

    [data]   where the smoke frames and styles come from, and the held-out split
    [model]  SKPN widths and ablation switches (``SKPNConfig``)
    [render] the fast layer's image size, views, steps, light
    [loss]   loss weights (paper: histogram 1, TV 10, temporal 300)
    [optim]  Adam, batch, schedule (paper: lr 2e-4, betas 0.9/0.999, x0.8 every 50 epochs)
    [run]    seed, device, extractor, logging, evaluation and checkpoint intervals
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass, field
from pathlib import Path

import tomllib

from ..conventions import (
    COLOUR_MATCH_GRADIENTS,
    DEFAULT_ENV_RADIANCE,
    DEFAULT_LAYER_SCHEME,
    DEVICES,
    EXTRACTOR_KINDS,
    LAYER_MARCH_STEPS,
    LAYER_SCHEMES,
    LOSS_MASKS,
    OBJECTIVES,
    ORBIT_DISTANCE,
    PRECISIONS,
    STYLE_LOSSES,
    TEMPORAL_GRADIENTS,
)
from ..scenes.cameras import validate_camera_distance
from .skpn import SKPNConfig


class ConfigError(ValueError):
    """A config file or ``--set`` override that cannot be used as given."""


PALETTE_HEAD_REMOVED = (
    "the palette output head was removed from the package "
    "(docs/decisions/2026-12-01-palette-head-removed.md); its code is available in git history "
    "before the commit that removed it, e.g. 20ba671"
)
RETIRED_MODEL_KEYS = {"head": "direct", "palette_spread": 1.0}
"""[model] keys of the removed palette head, with the value each held for the network that remains: configs and
checkpoints written while the head existed store them, and load as before with that value."""


def drop_retired_model_keys(table: dict, where: str) -> dict:
    """``table`` (a [model] table) without ``RETIRED_MODEL_KEYS`` at their old values; ``ConfigError`` for any
    other value of them (a palette-head network, which this version cannot build)."""
    for key, kept in RETIRED_MODEL_KEYS.items():
        if key in table and (isinstance(table[key], bool) or table[key] != kept):
            raise ConfigError(f"{where}: model.{key} = {table[key]!r}: {PALETTE_HEAD_REMOVED}.")
    return {key: value for key, value in table.items() if key not in RETIRED_MODEL_KEYS}


@dataclass
class DataConfig:
    smoke: str = "data/smoke32"  # a directory with manifest.json from ``python -m mistyle.data smoke``
    make: str = ""  # "tiny" or "cpu": generate that bundled dataset spec into ``smoke`` when it is missing
    styles: str = "offline"  # "offline" (the built-in style set) or a folder of images
    style_size: int = 128  # styles are centre-cropped/resized to this square size
    val_plumes: int = 1  # the last plumes of the manifest are held out for validation
    hue_augment: float = 0.0  # probability of a random hue rotation of each training style; > 0 also mirrors half


@dataclass
class RenderConfig:
    image_size: int = 160
    views: int = 4
    steps: int = LAYER_MARCH_STEPS  # N, ray-marching segments
    scheme: str = DEFAULT_LAYER_SCHEME
    radiance: float = DEFAULT_ENV_RADIANCE  # the training light's constant environment radiance Le
    camera_distance: float = ORBIT_DISTANCE  # radius of the training orbit (the box's longest side is 1)


@dataclass
class LossConfig:
    objective: str = "features"  # "features" (the paper's) | "sliced" (RGB + patch sliced Wasserstein)
    # "foreground": every pixel that sees the medium | "body" (docs/decisions/2026-11-25-style-fidelity-study.md)
    mask: str = "foreground"
    style: str = "histogram"  # objective "features": "histogram" | "gram" | "meanstd" (ablations)
    patch_weight: float = 0.05  # objective "sliced": weight of the patch term
    style_weight: float = 1.0
    rgb_weight: float = 1.0  # the histogram loss in RGB, beside the feature levels
    tv_weight: float = 10.0
    temporal_weight: float = 300.0
    temporal_gradient: str = (
        "both"  # "both" frames of the temporal term | "current": frame t only (t+1 is a fixed target)
    )
    # The product's colour match in the loop: each predicted albedo is given its style's colours by a
    # colour match fitted on it (without the feedback render) before it is rendered, so the network learns
    # what the match will make of its output.
    colour_match: bool = False
    # How the gradient passes the match: "map" holds the fitted map fixed (piecewise linear in the albedo);
    # "fit" also differentiates the fit (colour_match.fit_colour_match_torch), so what a refitted match would
    # undo gets no gradient and the arrangement is what is left to learn.
    colour_match_gradient: str = "map"


@dataclass
class OptimConfig:
    steps: int = 1000
    batch: int = 8
    lr: float = 2e-4
    betas: tuple[float, float] = (0.9, 0.999)
    lr_decay: float = 0.8
    decay_every_epochs: float = 50.0  # an epoch is one pass over the training frame pairs
    clip_grad: float = 0.0  # clip the gradient's global norm to this; 0: no clipping
    tune: tuple[str, ...] = ()  # train only the parameters whose names start with one of these; (): all


@dataclass
class RunConfig:
    seed: int = 0
    device: str = "cpu"  # "cpu" or "cuda"; picks the Mitsuba variant too
    extractor: str = "auto"  # "auto" | "vgg16" | "vgg16-random" | "filterbank"
    vgg_weights: str = ""
    log_every: int = 10
    eval_every: int = 200
    checkpoint_every: int = 200
    keep_checkpoints: bool = False  # also keep each checkpoint's weights as steps/step_XXXXXX.pt
    eval_styles: int = 6
    eval_densities: int = 2
    eval_views: int = 2
    threads: int = 0  # torch CPU threads; 0 keeps torch's default
    precision: str = (
        "fp32"  # the network's training forward pass: "fp32" | "bf16" (autocast; DAIN statistics stay fp32)
    )


@dataclass
class TrainConfig:
    data: DataConfig = field(default_factory=DataConfig)
    model: SKPNConfig = field(default_factory=SKPNConfig)
    render: RenderConfig = field(default_factory=RenderConfig)
    loss: LossConfig = field(default_factory=LossConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    run: RunConfig = field(default_factory=RunConfig)

    def validate(self) -> None:
        checks = [
            (self.data.make in ("", "tiny", "cpu"), "data.make must be '', 'tiny' or 'cpu'"),
            (self.data.style_size >= 16, "data.style_size must be >= 16"),
            (0.0 <= self.data.hue_augment <= 1.0, "data.hue_augment must be a probability in [0, 1]"),
            (self.data.val_plumes >= 1, "data.val_plumes must be >= 1 (validation needs unseen densities)"),
            (self.render.image_size >= 16, "render.image_size must be >= 16 (the extractor pools three times)"),
            (self.render.views >= 1 and self.render.steps >= 1, "render.views and render.steps must be >= 1"),
            (self.render.scheme in LAYER_SCHEMES, f"render.scheme must be one of {', '.join(LAYER_SCHEMES)}"),
            (
                math.isfinite(self.render.radiance) and self.render.radiance > 0,
                "render.radiance must be a finite number > 0",
            ),
            (self.loss.style in STYLE_LOSSES, f"loss.style must be one of {', '.join(STYLE_LOSSES)}"),
            (self.loss.objective in OBJECTIVES, f"loss.objective must be one of {', '.join(OBJECTIVES)}"),
            (self.loss.mask in LOSS_MASKS, f"loss.mask must be one of {', '.join(LOSS_MASKS)}"),
            (
                self.loss.temporal_gradient in TEMPORAL_GRADIENTS,
                f"loss.temporal_gradient must be one of {', '.join(TEMPORAL_GRADIENTS)}",
            ),
            (
                self.loss.colour_match_gradient in COLOUR_MATCH_GRADIENTS,
                f"loss.colour_match_gradient must be one of {', '.join(COLOUR_MATCH_GRADIENTS)}",
            ),
            (
                all(
                    math.isfinite(weight) and weight >= 0
                    for weight in (
                        self.loss.patch_weight,
                        self.loss.style_weight,
                        self.loss.rgb_weight,
                        self.loss.tv_weight,
                        self.loss.temporal_weight,
                    )
                ),
                "loss.patch_weight, style_weight, rgb_weight, tv_weight and temporal_weight must be finite and >= 0 "
                "(a negative weight rewards what its term penalises)",
            ),
            (self.optim.steps >= 1 and self.optim.batch >= 1, "optim.steps and optim.batch must be >= 1"),
            (self.optim.clip_grad >= 0, "optim.clip_grad must be >= 0 (0 turns clipping off)"),
            (
                math.isfinite(self.optim.lr) and self.optim.lr > 0 and 0 < self.optim.lr_decay <= 1,
                "optim.lr must be a finite number > 0 and optim.lr_decay in (0, 1]",
            ),
            (
                len(self.optim.betas) == 2 and all(0 <= beta < 1 for beta in self.optim.betas),
                "optim.betas must be two numbers in [0, 1), e.g. [0.9, 0.999]",
            ),
            (
                math.isfinite(self.optim.decay_every_epochs) and self.optim.decay_every_epochs > 0,
                "optim.decay_every_epochs must be a finite number > 0",
            ),
            (self.run.threads >= 0, "run.threads must be >= 0 (0 keeps torch's default)"),
            (
                min(self.run.eval_styles, self.run.eval_densities, self.run.eval_views) >= 1,
                "run.eval_styles, run.eval_densities and run.eval_views must be >= 1",
            ),
            (self.run.device in DEVICES, f"run.device must be one of {', '.join(DEVICES)}"),
            (self.run.precision in PRECISIONS, f"run.precision must be one of {', '.join(PRECISIONS)}"),
            (self.run.extractor in EXTRACTOR_KINDS, f"run.extractor must be one of {', '.join(EXTRACTOR_KINDS)}"),
            (
                min(self.run.log_every, self.run.eval_every, self.run.checkpoint_every) >= 1,
                "run.log_every, run.eval_every and run.checkpoint_every must be >= 1",
            ),
        ]
        for ok, message in checks:
            if not ok:
                raise ConfigError(message + ".")
        try:
            validate_camera_distance(self.render.camera_distance, "render.camera_distance")
        except ValueError as error:
            raise ConfigError(str(error)) from None
        try:
            SKPNConfig.__post_init__(self.model)
        except ValueError as error:
            raise ConfigError(f"[model]: {error}") from None


def load_config(path: str | Path | None = None, overrides: list[str] = ()) -> TrainConfig:
    """The defaults, updated by the TOML file at ``path`` and then by ``section.key=value`` strings."""
    config = TrainConfig()
    if path is not None:
        path = Path(path)
        try:
            table = tomllib.loads(path.read_text())
        except FileNotFoundError:
            raise ConfigError(
                f"Config file {path} does not exist; see configs/ for tiny.toml, cpu.toml, paper.toml."
            ) from None
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as error:
            raise ConfigError(f"Config file {path} is not valid TOML: {error}") from None
        _update(config, table, where=str(path))
    return apply_overrides(config, overrides)


def apply_overrides(config: TrainConfig, overrides: list[str]) -> TrainConfig:
    """``config`` updated in place by ``section.key=value`` strings (``--set``; the value in TOML
    syntax, or a bare word for a string), then validated."""
    for override in overrides:
        key, sep, text = override.partition("=")
        if not sep or "." not in key:
            raise ConfigError(f"--set takes section.key=value, e.g. optim.lr=1e-3; got {override!r}.")
        try:
            value = tomllib.loads(f"value = {text}")["value"]
        except tomllib.TOMLDecodeError:
            value = text  # a bare word: a string
        section, _, name = key.strip().partition(".")
        _update(config, {section: {name: value}}, where="--set")
    config.validate()
    return config


def config_to_dict(config) -> dict:
    return dataclasses.asdict(config)


def config_from_dict(table: dict, where: str = "checkpoint") -> TrainConfig:
    """A config from its ``config_to_dict`` form (as stored in checkpoints), checked like a file's."""
    config = TrainConfig()
    _update(config, table, where=where)
    config.validate()
    return config


def to_toml(table: dict) -> str:
    """The resolved config as TOML (two levels of tables, scalars and lists)."""

    def literal(value):
        if isinstance(value, bool):
            return "true" if value else "false"
        if isinstance(value, (int, float)):
            return repr(value)
        if isinstance(value, (list, tuple)):
            return "[" + ", ".join(literal(v) for v in value) + "]"
        return '"' + str(value).replace("\\", "\\\\").replace('"', '\\"') + '"'

    lines = []
    for section, values in table.items():
        lines.append(f"[{section}]")
        lines += [f"{key} = {literal(value)}" for key, value in values.items()]
        lines.append("")
    return "\n".join(lines)


def _update(target, table: dict, where: str) -> None:
    if isinstance(target, SKPNConfig):
        table = drop_retired_model_keys(table, where)
    fields = {f.name: f for f in dataclasses.fields(target)}
    hints = typing.get_type_hints(type(target))
    for key, value in table.items():
        if key not in fields:
            raise ConfigError(
                f"{where}: unknown key {key!r} in [{type(target).__name__}]; known keys: {', '.join(fields)}."
            )
        current = getattr(target, key)
        if dataclasses.is_dataclass(current):
            if not isinstance(value, dict):
                raise ConfigError(f"{where}: [{key}] must be a table, got {value!r}.")
            _update(current, value, where=f"{where} [{key}]")
        else:
            setattr(target, key, _coerce(value, hints[key], f"{where}: {key}"))


def _coerce(value, hint, name: str):
    origin = typing.get_origin(hint)
    if origin is tuple:
        items = typing.get_args(hint)
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{name} must be a list, got {value!r}.")
        if items[-1] is Ellipsis:
            items = (items[0],) * len(value)
        if len(items) != len(value):
            raise ConfigError(f"{name} must have {len(items)} entries, got {len(value)}.")
        return tuple(_coerce(v, t, name) for v, t in zip(value, items))
    if hint is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if hint in (int, float, str, bool) and (type(value) is hint):
        return value
    raise ConfigError(f"{name} must be {getattr(hint, '__name__', hint)}, got {value!r} ({type(value).__name__}).")
