"""The SKPN training loop (paper Sec. 4.4-4.6), one process or many under ``torchrun``.

Each update pairs frame t and t+1 of smoke examples (with frame t's velocity and cached Ls grid)
with training styles, predicts both albedos, renders frame t from ``render.views`` random views on
the training orbit through the fast layer, and minimises

    style_weight * (histogram loss on features + rgb_weight * histogram loss in RGB)
    + tv_weight * TV(V_t) + temporal_weight * |V_{t+1} - W(V_t, U_t)|^2.

Outputs in ``<out>/``: ``config.toml`` (resolved), ``metrics.jsonl`` (one object per logged step),
``last.pt`` (every ``run.checkpoint_every`` steps, on Ctrl-C and at the end), ``final.pt``,
``best.pt`` (weights of the lowest fast-layer validation RGB SWD), ``steps/step_XXXXXX.pt`` (weights
at every checkpoint, with ``run.keep_checkpoints``), ``previews/step_XXXXXX.png`` and TensorBoard
events in ``tb/``. With ``loss.objective = "sliced"`` the style term is ``objective.style.SlicedObjective``.

The run folder is mistyle's (``mistyle.ownership``): its manifest (kind ``train``) records each file as
it is written, only the files just written being hashed, and what is being written counts as
mistyle's should the run be killed. A folder holding any file mistyle did not write is refused
before anything is written; a run an older mistyle wrote (no manifest, nothing but a run's files) is
taken over when resumed from its ``last.pt``.
"""

from __future__ import annotations

import math
import os
import resource
import signal
import time
from pathlib import Path

import numpy as np
import torch
import torch.distributed as dist

from ..files import atomic_write_bytes, check_writable_dir, write_png
from ..files.paths import one_line
from ..integrators import prepare_density
from ..model.checkpoint import (
    CHECKPOINT_FORMAT,
    build_model,
    export_checkpoint,
    load_checkpoint,
    save_checkpoint,
)
from ..model.config import TrainConfig, config_from_dict, config_to_dict, drop_retired_model_keys, to_toml
from ..model.features import make_extractor
from ..model.skpn import parameter_count
from ..objective.losses import temporal_loss, tv_loss
from ..objective.masks import body_mask
from ..objective.metrics import (
    foreground_mask,
    multiview_spread,
    style_distance,
    style_fidelity,
)
from ..objective.style import make_objective
from ..progress import bar, status
from ..scenes import CameraPath
from ..tone import tone_map
from ..version import __version__
from .dataset import SmokePairs, StyleSet, augment_styles
from .run_folder import RUN_FILES, RUN_KIND, RUN_LAYOUT, RunLog, check_run_folder, record_files, trim_metrics


class Interrupted(Exception):
    """Raised out of the loop after Ctrl-C (or SIGTERM) once the checkpoint is safely written."""


def device_for(config: TrainConfig) -> torch.device:
    """The torch device, with the matching Mitsuba variant selected (``backend.use_variant``)."""
    from ..backend import use_variant

    if config.run.device == "cuda" and not torch.cuda.is_available():
        raise ValueError('run.device = "cuda" but torch sees no CUDA device; use --device cpu.')
    device = torch.device(config.run.device)
    if device.type == "cuda" and dist.is_initialized():
        device = torch.device("cuda", int(os.environ.get("LOCAL_RANK", 0)))
        torch.cuda.set_device(device)
    use_variant(device.type)
    return device


class Trainer:
    def __init__(
        self,
        config: TrainConfig,
        out: Path,
        resume: bool = False,
        log=status,
        init: Path | None = None,
        recipe: dict | None = None,
    ):
        self.config, self.out = config, Path(out)
        self.recipe = recipe  # train.recipes: which recipe and stage this run is, stored in its checkpoints
        self.rank, self.world = (dist.get_rank(), dist.get_world_size()) if dist.is_initialized() else (0, 1)
        self.log = log if self.rank == 0 else (lambda *a, **k: None)
        self._bar = None  # the progress bar of ``run`` (rank 0)
        if config.optim.batch % self.world:
            raise ValueError(f"optim.batch={config.optim.batch} must be divisible by the {self.world} processes.")
        checkpoint = None
        if not resume and (self.out / "last.pt").exists():
            raise ValueError(
                f"{self.out} already holds a run (last.pt); pass --resume to continue it, or choose another --out."
            )
        if resume:
            if not (self.out / "last.pt").is_file():
                raise ValueError(
                    f"No checkpoint at {self.out / 'last.pt'}; start without --resume, "
                    "or give the --out of the run to resume."
                )
            checkpoint = load_checkpoint(self.out / "last.pt")
            saved = config_from_dict(checkpoint["config"])
            if saved.optim.steps != config.optim.steps:
                self.log(f"resume: optim.steps {saved.optim.steps} -> {config.optim.steps}")
                saved.optim.steps = config.optim.steps
            config.model.style_channels = saved.model.style_channels  # set from the extractor, not by users
            if config_to_dict(saved) != config_to_dict(config):
                self.log("resume: continuing with the checkpoint's config (only optim.steps may change on --resume)")
            self.config = config = saved
        check_run_folder(self.out, resume)
        if resume and self.rank == 0:
            from ..ownership import adopt_older

            adopt_older(self.out, RUN_KIND, RUN_LAYOUT)  # its last.pt proves it a run of mistyle's
        if self.rank == 0:
            check_writable_dir(self.out)
        if config.run.threads:
            torch.set_num_threads(config.run.threads)
        self.device = device_for(config)
        self.data = SmokePairs(config.data.smoke, config.data.val_plumes, config.data.make, log=self.log)
        self.styles = StyleSet(config.data.styles, config.data.style_size)
        self.extractor = make_extractor(config.run.extractor, config.run.vgg_weights or None).to(self.device)
        self.log(
            f"feature extractor: {self.extractor.name}"
            + (
                ""
                if self.extractor.name.startswith("vgg16-imagenet")
                else " (offline: no VGG16 ImageNet weights given)"
            )
        )
        torch.manual_seed(config.run.seed)
        self.model = build_model(config, self.extractor).to(self.device)
        self.network = self.model
        if self.world > 1:
            self.network = torch.nn.parallel.DistributedDataParallel(self.model)
        self.optimizer = torch.optim.Adam(self.trained_parameters(), lr=config.optim.lr, betas=config.optim.betas)
        steps_per_epoch = max(1, len(self.data.train) // config.optim.batch)
        self.scheduler = torch.optim.lr_scheduler.StepLR(
            self.optimizer,
            step_size=max(1, round(config.optim.decay_every_epochs * steps_per_epoch)),
            gamma=config.optim.lr_decay,
        )
        self.objective = make_objective(config.loss, self.extractor)
        self._responses = {}  # loss.colour_match: the grey response of each training frame seen
        self.path = CameraPath(distance=config.render.camera_distance)
        self.rng = np.random.default_rng([config.run.seed, self.rank])
        self.step, self.seconds = 0, 0.0
        if checkpoint is not None:
            self._restore(checkpoint)
        elif init is not None:
            self._initialise_from(Path(init))
        self.best = math.inf
        self.interrupted = False
        self.run_log = RunLog(self.out)
        self.log(
            f"SKPN: {parameter_count(self.model) / 1e6:.2f} M parameters; {len(self.data.train)} training pairs "
            f"({self.data.shape} voxels), {len(self.styles.train)} training styles; "
            f"{len(self.data.val)} validation pairs, {len(self.styles.val)} validation styles"
        )

    def trained_parameters(self) -> list:
        """The parameters ``optim.tune`` names (by prefix; all when empty); the others are frozen, so the
        backward pass stops where the trained ones end."""
        prefixes = tuple(self.config.optim.tune)
        named = list(self.model.named_parameters())
        trained = [parameter for name, parameter in named if not prefixes or name.startswith(prefixes)]
        if not trained:
            names = sorted({name.split(".")[0] for name, _ in named})
            raise ValueError(f"optim.tune = {list(prefixes)} names no parameter; the model's parts are {names}.")
        chosen = {id(parameter) for parameter in trained}
        for _, parameter in named:
            parameter.requires_grad_(id(parameter) in chosen)
        return trained

    # ------------------------------------------------------------------ one update
    def sample_batch(self) -> dict:
        per_rank = self.config.optim.batch // self.world
        pairs = [self.data.train[i] for i in self.rng.integers(len(self.data.train), size=per_rank)]
        style_ids = self.rng.integers(len(self.styles.train), size=per_rank)
        views = self.path.sample(self.config.render.views, self.rng)
        frames = [self.data.load(pair) for pair in pairs]
        styles = augment_styles(self.styles.train[style_ids], self.rng, self.config.data.hue_augment)
        return {"frames": frames, "styles": styles.to(self.device), "views": views}

    def losses(self, batch: dict) -> tuple[dict, torch.Tensor]:
        config, device = self.config, self.device
        frames = batch["frames"]

        def stack(key):
            return torch.from_numpy(np.stack([frame[key] for frame in frames])).to(device)

        style = self._style_inputs(batch["styles"])
        with self._autocast():
            if config.loss.temporal_gradient == "current":
                # Frame t+1 is only the temporal term's target: no gradient, so no backward pass through it.
                current = self.network(stack("density0")[:, None], style).float()
                with torch.no_grad():
                    following = self.model(stack("density1")[:, None], style).float()
            else:
                density = torch.cat([stack("density0"), stack("density1")])[:, None]
                albedo = self.network(density, style.repeat(2)).float()
                current, following = albedo[: len(frames)], albedo[len(frames) :]
        if config.loss.colour_match:
            current, following = self._colour_matched(current, following, frames, batch["styles"])
        prepared = [prepare_density(f["density0"], self.data.density_scale, ls=f["ls0"]) for f in frames]
        images, white = self._render(current, prepared, batch["views"], white=True)
        loss_hist = self.objective.loss(
            images,
            self.objective.targets(batch["styles"], style.levels),
            body_mask(white.flatten(0, 1)) if config.loss.mask == "body" else None,
        )
        loss_tv = tv_loss(current)
        loss_temp = temporal_loss(following, current, stack("velocity0"))
        loss = (
            config.loss.style_weight * loss_hist
            + config.loss.tv_weight * loss_tv
            + config.loss.temporal_weight * loss_temp
        )
        terms = {"loss": loss, "loss_hist": loss_hist, "loss_tv": loss_tv, "loss_temp": loss_temp}
        return terms, images

    def _colour_matched(self, current, following, frames, styles) -> tuple[torch.Tensor, torch.Tensor]:
        """``current`` and ``following`` ``(B, 3, D, H, W)`` with each item's colour match (``loss.colour_match``):
        fitted on the item's frame-t albedo as the product fits it, applied to both frames (the sequence
        rule: one map per style), differentiable in the albedo."""
        from ..colour_match import InvisibleMedium, fit_colour_match, fit_colour_match_torch, grey_response

        config = self.config
        through_fit = config.loss.colour_match_gradient == "fit"
        light = dict(
            density_scale=self.data.density_scale,
            radiance=config.render.radiance,
            camera_distance=config.render.camera_distance,
        )
        matched_current, matched_following = [], []
        for item, frame in enumerate(frames):
            inside = torch.from_numpy(frame["density0"] > 0).to(self.device)
            inside_next = torch.from_numpy(frame["density1"] > 0).to(self.device)
            try:
                key = frame["density0"].tobytes()  # the grey response depends on the density only: once per frame
                if key not in self._responses:
                    self._responses[key] = grey_response(frame["density0"], **light)
                seed = int(self.rng.integers(2**31))
                if through_fit:
                    match = fit_colour_match_torch(
                        current[item],
                        frame["density0"],
                        styles[item].permute(1, 2, 0).cpu().numpy(),
                        density_scale=light["density_scale"],
                        response=self._responses[key],
                        seed=seed,
                    )
                    matched_current.append(match.apply(current[item], inside))
                    matched_following.append(match.detached().apply(following[item], inside_next))
                    continue
                # Without the feedback render (step 4 of colour_match): a quarter of the cost, a small correction.
                match = fit_colour_match(
                    current[item].detach().permute(1, 2, 3, 0).cpu().numpy(),
                    frame["density0"],
                    styles[item].permute(1, 2, 0).cpu().numpy(),
                    **light,
                    seed=seed,
                    feedback=False,
                    response=self._responses[key],
                )
            except InvisibleMedium:  # nothing to match on this item: it trains unmatched
                matched_current.append(current[item])
                matched_following.append(following[item])
                continue
            matched_current.append(match.apply_torch(current[item], inside))
            matched_following.append(match.apply_torch(following[item], inside_next))
        return torch.stack(matched_current), torch.stack(matched_following)

    def _style_inputs(self, styles: torch.Tensor):
        return self.model.encode_style(styles, self.extractor)

    def _autocast(self):
        """The network's forward pass in ``run.precision`` (bfloat16 autocast, or plain float32)."""
        return torch.autocast(self.device.type, dtype=torch.bfloat16, enabled=self.config.run.precision == "bf16")

    def _render(self, albedo, prepared, views, white: bool = False):
        from ..bridge_torch import render_views

        size = self.config.render.image_size
        return render_views(
            albedo,
            prepared,
            views,
            size,
            steps=self.config.render.steps,
            scheme=self.config.render.scheme,
            radiance=self.config.render.radiance,
            white=white,
        )

    def train_step(self) -> tuple[dict, dict]:
        started = time.perf_counter()
        batch = self.sample_batch()
        terms, images = self.losses(batch)
        self.optimizer.zero_grad(set_to_none=True)
        terms["loss"].backward()
        # The gradient's norm before clipping (logged; clipped to optim.clip_grad when that is > 0).
        terms["grad_norm"] = torch.nn.utils.clip_grad_norm_(
            self.model.parameters(), self.config.optim.clip_grad or math.inf
        )
        self.optimizer.step()
        self.scheduler.step()
        self.step += 1
        values = {key: float(value.detach()) for key, value in terms.items()}
        if self.world > 1:
            packed = torch.tensor([values[k] for k in sorted(values)], dtype=torch.float64, device=self.device)
            dist.all_reduce(packed)
            values = dict(zip(sorted(values), (packed / self.world).tolist()))
        self.seconds += time.perf_counter() - started
        return values, {"styles": batch["styles"], "images": images.detach()}

    # ------------------------------------------------------------------ the run
    def run(self) -> Path:
        config = self.config
        if self.rank == 0:
            self.out.mkdir(parents=True, exist_ok=True)
            record_files(self.out, add=RUN_FILES)
            atomic_write_bytes(self.out / "config.toml", to_toml(config_to_dict(config)).encode())
            record_files(self.out, rewritten=["config.toml"])
            seen = [record.get("val_rgb_swd") for record in trim_metrics(self.out, self.step)]
            # A resumed run's best so far, so that best.pt only improves.
            self.best = min([value for value in seen if isinstance(value, (int, float))], default=math.inf)
        previous = {sig: signal.signal(sig, self._on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
        self._bar = bar(config.optim.steps, "training", initial=self.step) if self.rank == 0 else None
        try:
            if self.step == 0:
                self.run_log.record({"step": 0, **self.evaluate()}, self.rank)
            window_start, window_steps = time.perf_counter(), 0
            while self.step < config.optim.steps:
                values, visuals = self.train_step()
                window_steps += 1
                if self._bar is not None:
                    self._bar.update(1)
                if self.world > 1:  # every rank stops at the same step, or the checkpoint gather would hang
                    flag = torch.tensor([float(self.interrupted)], device=self.device)
                    dist.all_reduce(flag, op=dist.ReduceOp.MAX)
                    self.interrupted = bool(flag.item())
                if not all(math.isfinite(v) for v in values.values()):
                    raise FloatingPointError(f"step {self.step}: the loss is not finite ({values}); lower optim.lr.")
                evaluate = self.step % config.run.eval_every == 0 or self.step == config.optim.steps
                if self.step % config.run.log_every == 0 or evaluate or self.interrupted:
                    rate = window_steps / max(time.perf_counter() - window_start, 1e-9)
                    window_start, window_steps = time.perf_counter(), 0
                    record = {
                        "step": self.step,
                        **values,
                        "lr": self.scheduler.get_last_lr()[0],
                        "seconds": self.seconds,
                        "steps_per_second": rate,
                        "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                    }
                    if evaluate:
                        record.update(self.evaluate())
                        self.run_log.images(self.step, visuals, self.rank)
                        self._keep_best(record)
                    self.run_log.record(record, self.rank)
                    self._progress(record)
                if self.step % config.run.checkpoint_every == 0 or self.interrupted:
                    kept = [f"steps/step_{self.step:06d}.pt"] if config.run.keep_checkpoints else []
                    if self.rank == 0:
                        record_files(self.out, add=kept)
                    self.save(self.out / "last.pt")
                    if kept and self.rank == 0:  # weights only, for experiments/validation_curve.py
                        export_checkpoint(self.out / "last.pt", self.out / kept[0])
                    if self.rank == 0:
                        record_files(self.out, rewritten=["last.pt", "metrics.jsonl", *kept], done=kept)
                if self.interrupted:
                    raise Interrupted()
            self.save(self.out / "last.pt")
            final = self.save(self.out / "final.pt")
            if self.world > 1:  # leave together: a rank that tears gloo down while rank 0 still writes can abort it
                dist.barrier()
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            self.run_log.close()
            if self._bar is not None:
                self._bar.close()
            if self.rank == 0:
                events = [p.relative_to(self.out).as_posix() for p in (self.out / "tb").glob("events.out.tfevents.*")]
                record_files(self.out, rewritten=[*RUN_FILES, *events], done=RUN_FILES)
        return final

    def _keep_best(self, record: dict) -> None:
        """``best.pt`` (weights only): the evaluation with the lowest fast-layer validation RGB SWD so far (model
        selection on the validation split; the held-out benchmark split is never looked at)."""
        value = record.get("val_rgb_swd")  # only rank 0 evaluates, so only rank 0 writes (weights only: no gather)
        if self.rank == 0 and value is not None and value < self.best:
            self.best = value
            save_checkpoint(self.out / "best.pt", self._inference_payload())
            record_files(self.out, rewritten=["best.pt"])

    def _initialise_from(self, path: Path) -> None:
        """Start from another run's weights (a training or exported checkpoint): same architecture and extractor."""
        checkpoint = load_checkpoint(path)
        if checkpoint["extractor"] != self.extractor.name:
            raise ValueError(
                f"--init {path} was trained with the {checkpoint['extractor']} extractor, this run has "
                f"{self.extractor.name}."
            )
        # A palette-head network (the head was removed): ConfigError naming the commit that still has it.
        drop_retired_model_keys(checkpoint.get("config", {}).get("model", {}), f"--init {path}")
        try:
            missing, unexpected = self.model.load_state_dict(checkpoint["model"], strict=False)
        except RuntimeError as error:
            lines = [line.strip() for line in str(error).splitlines()[1:] if line.strip()]
            first = lines[0] if lines else one_line(error)  # torch's first line only says where it failed
            raise ValueError(
                f"--init {path} does not fit this run's [model] config ({first[:300]}); give the [model] settings "
                "of the run that made it."
            ) from None
        # A noise site added to a network without one starts at zero: the network computes what it did.
        missing = [key for key in missing if not key.startswith("noise_predictor.")]
        if missing or unexpected:
            raise ValueError(
                f"--init {path} does not fit this run's [model] config (missing {missing[:3]}, unexpected "
                f"{unexpected[:3]})."
            )
        self.log(f"initialised from the weights of {path} (step {checkpoint.get('step', '?')} of its run)")

    def _on_signal(self, signum, frame):
        if self.interrupted:  # a second Ctrl-C: stop at once
            raise KeyboardInterrupt
        self.interrupted = True
        self.log(  # the signal may come inside a step or after its count went up: no step number here
            f"\n{signal.Signals(signum).name}: finishing the step in progress, "
            f"saving {self.out / 'last.pt'} and stopping "
            "(press Ctrl-C again to abort without saving)"
        )

    # ------------------------------------------------------------------ evaluation
    @torch.no_grad()
    def evaluate(self) -> dict:
        """Style metrics of held-out styles on held-out densities from fixed views (rank 0 only): the mean
        ``style_distance`` per view, and the medians of the fidelity benchmark's metrics
        (``val_rgb_swd``, ``val_patch_swd``, ``val_hue_coverage``) over (density, style) pairs, on the
        fast layer's renders."""
        if self.rank != 0:
            return {}
        config = self.config
        pick = (
            np.linspace(0, len(self.data.val) - 1, min(config.run.eval_densities, len(self.data.val)))
            .round()
            .astype(int)
        )
        pairs = [self.data.val[i] for i in pick]
        style_ids = (
            np.linspace(0, len(self.styles.val) - 1, min(config.run.eval_styles, len(self.styles.val)))
            .round()
            .astype(int)
        )
        views = self.path.held_out(config.run.eval_views)
        self.model.eval()
        swd, hist, spreads, rows, fidelity, dark = [], [], [], [], [], 0
        for pair in pairs:
            frame = self.data.load(pair)
            density = torch.from_numpy(frame["density0"])[None, None].to(self.device)
            prepared = prepare_density(frame["density0"], self.data.density_scale, ls=frame["ls0"])
            for index in style_ids:
                style = self.styles.val[index : index + 1].to(self.device)
                albedo = self.model(density, self._style_inputs(style))
                if config.loss.colour_match:  # what the product shows of it
                    albedo = self._colour_matched(albedo, albedo, [frame], style)[0]
                images = self._render(albedo, [prepared], views)[0]
                style_np = style[0].permute(1, 2, 0).cpu().numpy()
                renders = [image.permute(1, 2, 0).cpu().numpy() for image in images]
                rows.append(torch.cat([_fit(style[0], images.shape[-2:]), *tone_map(images)], dim=-1))
                renders = [render for render in renders if foreground_mask(render).any()]
                if (
                    not renders
                ):  # no pixel bright enough to count as medium: an albedo near black, no colours to compare
                    dark += 1
                    continue
                per_view = [style_distance(render, style_np) for render in renders]
                fidelity.append(style_fidelity(renders, style_np))
                swd += [d["swd"] for d in per_view]
                hist += [d["hist"] for d in per_view]
                spreads.append(multiview_spread([d["swd"] for d in per_view])["relative_std"])
        self.model.train()
        if rows:
            preview = torch.cat(rows, dim=-2).permute(1, 2, 0).clamp(0, 1).cpu().numpy()
            name = f"previews/step_{self.step:06d}.png"
            record_files(self.out, add=[name])
            write_png(self.out / name, preview, srgb=False)
            record_files(self.out, rewritten=[name], done=[name])
            self.run_log.tensorboard().add_image("val/preview", preview, self.step, dataformats="HWC")
        record = {"val_dark_renders": dark} if dark else {}
        if not fidelity:
            self.log(f"step {self.step}: every validation render is black (albedo near zero); no validation metrics")
            return record
        return {
            "val_swd": float(np.mean(swd)),
            "val_hist": float(np.mean(hist)),
            "val_view_spread": float(np.mean(spreads)),
            **{f"val_{key}": float(np.median([row[key] for row in fidelity])) for key in fidelity[0]},
            **record,
        }

    # ------------------------------------------------------------------ logging
    def _progress(self, record: dict) -> None:
        """The losses on the progress bar (on a terminal), else as a status line (logs, ``nohup``)."""
        if self.rank != 0:
            return
        text = (
            f"loss {record['loss']:.4g} (hist {record['loss_hist']:.4g}, tv {record['loss_tv']:.3g}, "
            f"temp {record['loss_temp']:.3g})"
        )
        if "val_swd" in record:
            text += f"  val_swd {record['val_swd']:.4f}"
        if self._bar is not None and not self._bar.disable:
            self._bar.set_postfix_str(text)
        else:
            status(f"step {record['step']}/{self.config.optim.steps}  {text}  {record['steps_per_second']:.2f} steps/s")

    # ------------------------------------------------------------------ checkpoints
    def _rng_states(self) -> list:
        state = {"numpy": self.rng.bit_generator.state, "torch": torch.get_rng_state()}
        if self.world == 1:
            return [state]
        states = [None] * self.world
        dist.all_gather_object(states, state)
        return states

    def save(self, path: Path) -> Path:
        states = self._rng_states()  # every rank joins the gather
        if self.rank != 0:
            return path
        payload = {
            **self._inference_payload(),
            "optimizer": self.optimizer.state_dict(),
            "scheduler": self.scheduler.state_dict(),
            "rng": states,
            "world_size": self.world,
        }
        return save_checkpoint(path, payload)

    def _inference_payload(self) -> dict:
        return {
            "format": CHECKPOINT_FORMAT,
            "mistyle_version": __version__,
            "step": self.step,
            "seconds": self.seconds,
            "config": config_to_dict(self.config),
            "extractor": self.extractor.name,
            "density_scale": self.data.density_scale,
            "model": self.model.state_dict(),
            **({"recipe": self.recipe} if self.recipe is not None else {}),
        }

    def _restore(self, checkpoint: dict) -> None:
        if checkpoint["extractor"] != self.extractor.name:
            raise ValueError(
                f"The checkpoint was trained with the {checkpoint['extractor']} extractor, "
                f"this run has {self.extractor.name}; give the same --vgg-weights / run.extractor."
            )
        if checkpoint["world_size"] != self.world:
            raise ValueError(
                f"The checkpoint was written by {checkpoint['world_size']} processes; resume with the same number."
            )
        try:
            self.model.load_state_dict(checkpoint["model"])
            self.optimizer.load_state_dict(checkpoint["optimizer"])
            self.scheduler.load_state_dict(checkpoint["scheduler"])
            state = checkpoint["rng"][self.rank]
            self.rng.bit_generator.state = state["numpy"]
            torch.set_rng_state(state["torch"])
            self.step, self.seconds = int(checkpoint["step"]), float(checkpoint["seconds"])
        except (KeyError, IndexError, TypeError, ValueError, RuntimeError) as error:
            raise ValueError(
                f"{self.out / 'last.pt'} does not fit this run ({type(error).__name__}: {str(error).splitlines()[0]}); "
                "resume with the config and mistyle version that wrote it, or start a new run in another --out."
            ) from None
        self.log(f"resumed from {self.out / 'last.pt'} at step {self.step}")


def _fit(image: torch.Tensor, size) -> torch.Tensor:
    return torch.nn.functional.interpolate(
        image[None], size=tuple(size), mode="bilinear", antialias=True, align_corners=False
    )[0]
