"""Training recipes: a named, complete way to make a checkpoint, run with one command.

    mistyle-train --recipe skpn_cpu --out runs/skpn_cpu     # the bundled network, every stage (hours on 2 cores)
    mistyle-train --recipe skpn_cpu --out runs/skpn_cpu     # again: finished stages are kept, the rest resumes
    mistyle-train --recipe tiny --out runs/tiny             # the same machinery in seconds (tests)

A recipe is stages run in order. Each stage trains one of the package's configs (``mistyle/configs/``)
with its overrides, starts from the previous stage's chosen weights (``init="previous"``), from another
recipe's shipped checkpoint (``init="recipe:NAME"``, checked by its SHA-256) or from scratch, and ends
by choosing one of its kept checkpoints (``select``):

* ``"last"``: the stage's final weights;
* ``"step:N"``: the weights of step N (a run that was stopped there, e.g. before it diverged);
* ``"validation"``: the kept checkpoint with the lowest median RGB SWD, as a ratio to the uniform
  baseline of the same pair, on the benchmark's ``validation`` split (the validation styles on
  ``VALIDATION_DENSITIES``, path traced and scored as the benchmark scores:
  ``mistyle.benchmark.runner``). Never the benchmark's held-out split.
* ``"validation:noise"``: the same split, the lowest mean of the median RGB SWD and median patch SWD
  ratios to the smooth-noise baseline with the colour match (``benchmark.methods``): for a network
  whose job is to beat that baseline.

Every checkpoint a recipe writes carries ``recipe`` (its name, the stage, and the whole recipe), and
``<out>/recipe.json`` records what each stage chose. The bundled network
(``mistyle/checkpoints/skpn_noise.pt``) is ``skpn_noise``'s: ``skpn_cpu``'s network
(``mistyle/checkpoints/skpn_cpu.pt``, kept: ``skpn_noise`` starts from it, and looks fitted with it load
with ``--checkpoint``) with a trained noise site (``docs/decisions/2026-12-02-noise-site.md``).
``skpn_cpu``'s stages and choices were made by hand (``docs/decisions/2026-11-25-training-notebook.md``),
and the recipe writes them down: the chosen steps of those runs are given with ``select``'s rule that
chose them (``Stage.chose``).
"""

from __future__ import annotations

import json
import shutil
from dataclasses import asdict, dataclass, field
from pathlib import Path

CONFIG_DIR = Path(__file__).resolve().parents[1] / "configs"
RECIPE_FILE, RECIPE_KIND = "recipe.json", "recipe"
SELECTIONS = ("last", "step:N", "validation", "validation:noise")
VALIDATION_RES, VALIDATION_SPP = 128, 16


@dataclass(frozen=True)
class Stage:
    name: str
    config: str  # a file name in mistyle/configs/
    overrides: tuple = ()  # --set values, e.g. ("optim.lr=1e-3",)
    init: str | None = None  # "previous": the previous stage's weights; "recipe:NAME": its product; None: scratch
    select: str = "last"  # see the module docstring
    chose: str = ""  # what the stage chose when it made the shipped checkpoint (a record, not an input)

    def __post_init__(self):
        if not (self.select in ("last", "validation", "validation:noise") or self.select.startswith("step:")):
            raise ValueError(f"Stage {self.name}: select must be one of {', '.join(SELECTIONS)}, got {self.select!r}.")
        if self.init not in (None, "previous") and not str(self.init).startswith("recipe:"):
            raise ValueError(f"Stage {self.name}: init must be None, 'previous' or 'recipe:NAME', got {self.init!r}.")


@dataclass(frozen=True)
class Recipe:
    name: str
    description: str
    stages: tuple
    product: str = ""  # the shipped checkpoint it made, if any
    product_sha256: str = ""  # that file's SHA-256, so the recipe names exactly one file
    # A commit of this repository that holds ``product`` when the working tree does not carry it (a
    # checkpoint only recipes start from): ``product_path`` takes it from the history.
    product_commit: str = ""

    def as_dict(self) -> dict:
        """The recipe as JSON values (lists, not tuples): what checkpoints and ``recipe.json`` store."""
        return json.loads(json.dumps(asdict(self)))


RECIPES = {
    recipe.name: recipe
    for recipe in (
        Recipe(
            "skpn_cpu",
            "the bundled network: the sliced objective at batch 4, then batch 8 with a decaying learning rate",
            (
                Stage(
                    "warmup",
                    "cpu_sliced.toml",
                    ("optim.lr=1e-3", "optim.clip_grad=0", "optim.steps=750"),
                    select="last",
                    chose="step 750 (the run diverged at step ~1550 at this learning rate)",
                ),
                Stage(
                    "sliced",
                    "cpu_sliced.toml",
                    ("optim.steps=4500",),
                    init="previous",
                    select="validation",
                    chose="step 1750 of this stage (total 2500): validation RGB 0.77x, patch 0.64x uniform",
                ),
                Stage(
                    "finetune",
                    "cpu_sliced_finetune.toml",
                    init="previous",
                    select="validation",
                    chose="step 1600 of this stage (total 4100): validation RGB 0.64x, patch 0.56x uniform",
                ),
            ),
            product="mistyle/checkpoints/skpn_cpu.pt",
            product_sha256="007e2df1cf7f1b17b6381db84c2b10e4f1fbae14991591d4993dd71fb0080078",
            product_commit="472cc5636068f087103da653918c812c67222099",
        ),
        Recipe(
            "skpn_noise",
            "skpn_cpu's network with a noise site (smooth noise fields weighted per style), only the site trained, "
            "the colour match in the loop",
            (
                Stage(
                    "noise",
                    "cpu_noise.toml",
                    init="recipe:skpn_cpu",
                    select="validation:noise",
                    chose="step 800 of 1200: validation 0.917 (mean of the median RGB and patch SWD x smooth noise)",
                ),
            ),
            product="mistyle/checkpoints/skpn_noise.pt",
            product_sha256="ccc2ae034752cc3adfe7798bde3d8b5624393c635554c169ac4d41a6d734a56e",
        ),
        Recipe(
            "tiny",
            "two short stages on the tiny dataset: the recipe machinery in seconds",
            (
                Stage("first", "tiny.toml", ("optim.steps=6", "run.checkpoint_every=3", "run.eval_every=100")),
                Stage(
                    "second",
                    "tiny.toml",
                    ("optim.steps=6", "run.checkpoint_every=3", "run.eval_every=100"),
                    init="previous",
                    select="step:3",
                ),
            ),
        ),
    )
}


def product_path(name: str) -> Path:
    """The shipped checkpoint recipe ``name`` made, checked against its SHA-256 (``Stage.init = "recipe:NAME"``)."""
    import hashlib

    made = recipe(name)
    if not made.product:
        raise ValueError(f"Recipe {name!r} ships no checkpoint to start from.")
    root = Path(__file__).resolve().parents[2]
    path = root / made.product
    if not path.is_file() and made.product_commit:
        restore_from_history(root, made.product_commit, made.product, path)
    if not path.is_file() or hashlib.sha256(path.read_bytes()).hexdigest() != made.product_sha256:
        raise ValueError(f"{path} is not the checkpoint recipe {name!r} made (SHA-256 {made.product_sha256[:12]}).")
    return path


def restore_from_history(root: Path, commit: str, relative: str, path: Path) -> None:
    """Write ``relative`` as committed in ``commit`` of the checkout at ``root`` to ``path``: a checkpoint the
    working tree leaves out (to keep the checkout small) is recovered from the history, not downloaded."""
    import subprocess

    from ..files import atomic_write_bytes

    try:
        blob = subprocess.run(
            ["git", "-C", str(root), "show", f"{commit}:{relative}"], capture_output=True, check=True, timeout=120
        ).stdout
    except (OSError, subprocess.SubprocessError) as error:
        raise ValueError(
            f"{relative} is not in this checkout and could not be read from commit {commit[:12]} of its git history "
            f"({type(error).__name__}); in a full clone of the repository run "
            f"'git show {commit[:12]}:{relative} > {relative}', or rebuild it with its recipe."
        ) from None
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, blob)


def recipe(name: str) -> Recipe:
    if name not in RECIPES:
        raise ValueError(f"Unknown recipe {name!r}; choose one of {', '.join(RECIPES)}.")
    return RECIPES[name]


@dataclass
class StageResult:
    stage: str
    run: str  # the stage's run folder
    chosen: str  # the chosen weights, copied to <run>/chosen.pt
    reason: str
    scores: dict = field(default_factory=dict)  # validation: checkpoint -> median RGB SWD x uniform


def run_recipe(chosen: Recipe, out: Path, overrides: list[str] | None = None, log=print) -> Path:
    """Run every stage of ``chosen`` into ``out/<n>_<stage>/``; returns the last stage's chosen weights.

    A stage whose ``chosen.pt`` exists is kept as it is; one with a ``last.pt`` resumes. ``overrides``
    (``--set``) apply to every stage, after the stage's own (e.g. ``run.device="cuda"``)."""
    from ..files import atomic_write_bytes
    from ..model.config import load_config
    from ..ownership import write_manifest
    from .run_folder import record_files
    from .trainer import Trainer

    out = Path(out)
    check_recipe_folder(out, chosen)
    out.mkdir(parents=True, exist_ok=True)
    results: list[StageResult] = []
    previous = None
    for number, stage in enumerate(chosen.stages, 1):
        folder = out / stage_folder(number, stage)
        pick = folder / "chosen.pt"
        if not pick.exists():
            keep = ["run.keep_checkpoints=true"]
            config = load_config(CONFIG_DIR / stage.config, [*stage.overrides, *keep, *(overrides or [])])
            resume = (folder / "last.pt").exists()
            init = None
            if stage.init == "previous" and not resume:
                init = previous
            elif stage.init and stage.init.startswith("recipe:") and not resume:
                init = product_path(stage.init.partition(":")[2])
            log(f"recipe {chosen.name}: stage {number}/{len(chosen.stages)} {stage.name} ({stage.config})")
            stamp = {"name": chosen.name, "stage": stage.name, "recipe": chosen.as_dict()}
            Trainer(config, folder, resume=resume, init=init, recipe=stamp).run()
            result = select(stage, folder, log=log)
            record_files(folder, add=["chosen.pt"])
            shutil.copyfile(result.chosen, pick)
            record_files(folder, rewritten=["chosen.pt"], done=["chosen.pt"])
            result.chosen = str(pick)
        else:
            result = StageResult(stage.name, str(folder), str(pick), "kept from an earlier run")
        results.append(result)
        previous = pick
        record = {"recipe": chosen.as_dict(), "stages": [asdict(r) for r in results]}
        atomic_write_bytes(out / RECIPE_FILE, (json.dumps(record, indent=1) + "\n").encode())
        write_manifest(out, RECIPE_KIND, [RECIPE_FILE])
    return previous


def stage_folder(number: int, stage: Stage) -> str:
    return f"{number}_{stage.name}"


def check_recipe_folder(out: Path, chosen: Recipe) -> None:
    """``ValueError`` (one line) unless ``out`` may take the recipe: missing, or holding its stages'
    folders (each checked by its run) and its own ``recipe.json``, nothing else."""
    from ..ownership import check_replaceable, read_manifest, write_manifest

    if out.exists() and not out.is_dir():
        raise ValueError(f"The output path {out} is a file; choose a folder for --out.")
    stages = {stage_folder(number, stage) for number, stage in enumerate(chosen.stages, 1)}

    def in_a_stage(name: str) -> bool:
        return name.split("/")[0] in stages

    if (out / RECIPE_FILE).is_file() and read_manifest(out) is None:  # an older mistyle's recipe folder
        try:
            older = json.loads((out / RECIPE_FILE).read_text()).get("recipe", {}).get("name") == chosen.name
        except (OSError, ValueError, UnicodeDecodeError, AttributeError):
            older = False
        if older:
            write_manifest(out, RECIPE_KIND, [RECIPE_FILE])
    check_replaceable(out, "--out", also_ours=in_a_stage)


def kept_checkpoints(folder: Path) -> list[Path]:
    """A run's kept weights (``steps/step_*.pt``), by step."""
    return sorted((Path(folder) / "steps").glob("step_*.pt"))


def select(stage: Stage, folder: Path, log=print, **validation) -> StageResult:
    """The checkpoint ``stage.select`` chooses among the run in ``folder``."""
    folder = Path(folder)
    if stage.select == "last":
        return StageResult(stage.name, str(folder), str(folder / "final.pt"), "the stage's final weights")
    if stage.select.startswith("step:"):
        step = int(stage.select.partition(":")[2])
        path = folder / "steps" / f"step_{step:06d}.pt"
        if not path.exists():
            found = ", ".join(p.name for p in kept_checkpoints(folder)) or "none"
            raise ValueError(f"Stage {stage.name}: no kept checkpoint of step {step} in {folder} (kept: {found}).")
        return StageResult(stage.name, str(folder), str(path), f"step {step}")
    against = "smooth_noise" if stage.select == "validation:noise" else "uniform"
    scores = validation_scores(kept_checkpoints(folder), log=log, against=against, **validation)
    if not scores:
        raise ValueError(f"Stage {stage.name}: {folder / 'steps'} holds no kept checkpoint to choose from.")
    best = min(scores, key=scores.get)
    reason = (
        "lowest mean of the median validation RGB and patch SWD x smooth noise"
        if against == "smooth_noise"
        else "lowest median validation RGB SWD x uniform"
    )
    return StageResult(stage.name, str(folder), best, reason, scores)


def validation_scores(
    checkpoints: list[Path],
    styles: int = 0,
    res: int = VALIDATION_RES,
    spp: int = VALIDATION_SPP,
    densities: list | None = None,
    cache=Path("data") / "heldout",
    log=print,
    against: str = "uniform",
) -> dict[str, float]:
    """``checkpoint -> median RGB SWD x uniform`` on the benchmark's ``validation`` split (drawn like the
    held-out split: the validation styles on ``VALIDATION_DENSITIES``), each network's feed-forward
    output scored as ``mistyle-bench`` scores ``network``. ``styles``: only the first that many
    validation styles (0: all); ``densities``: other ``(Z, Y, X)`` grids than ``VALIDATION_DENSITIES``
    (made once and cached in ``cache``). ``against="smooth_noise"``: the mean of the median RGB and patch
    SWD ratios to the smooth-noise baseline with the colour match instead. (The recipes' recorded
    choices, ``Stage.chose``, were made on the split of their day: 13 paintings held back from the
    training collection, on the smoke density alone.)"""
    import numpy as np

    from ..benchmark.methods import smooth_noise, uniform_baseline
    from ..benchmark.runner import metric_views, score
    from ..benchmark.splits import split_pairs, split_styles
    from ..data.heldout import held_out_density
    from ..files import load_style
    from ..pipeline import Pipeline, PipelineSettings

    pairs = split_pairs("validation")
    records = split_styles("validation")
    names = list(dict.fromkeys(name for _, name in pairs))[: styles or None]
    pictures = [load_style(records[name]["path"]) for name in names]
    if densities is None:
        densities = [held_out_density(spec, cache) for spec in dict.fromkeys(spec for spec, _ in pairs)]
    baselines: dict = {}
    scores = {}
    for path in checkpoints:
        pipeline = Pipeline(PipelineSettings(checkpoint=path, refine_steps=0, refine_path_steps=0))
        views = metric_views(pipeline.camera_distance)
        options = {"res": res, "spp": spp, "density_scale": pipeline.density_scale, "radiance": pipeline.radiance}
        ratios = []
        for d, density in enumerate(densities):
            for s, style in enumerate(pictures):
                if (d, s) not in baselines:
                    if against == "smooth_noise":  # the benchmark's smooth_noise method
                        field = smooth_noise(density.shape)
                        baseline = pipeline.stylizer.match_colours(
                            [field], [density], style, density_scale=pipeline.density_scale
                        )[0]
                    else:
                        baseline = uniform_baseline(
                            density, style, views, density_scale=pipeline.density_scale, radiance=pipeline.radiance
                        )
                    baselines[d, s] = score(density, baseline, style, views, **options)[0]
                albedo = pipeline.stylize(density, style).albedos[0]
                metrics = score(density, albedo, style, views, **options)[0]
                ratios.append([metrics[key] / baselines[d, s][key] for key in ("rgb_swd", "patch_swd")])
        ratios = np.asarray(ratios)
        if against == "smooth_noise":
            scores[str(path)] = float(np.mean(np.median(ratios, axis=0)))
            log(f"validation: {path.name}: mean of median RGB and patch SWD x smooth noise {scores[str(path)]:.3f}")
        else:
            scores[str(path)] = float(np.median(ratios[:, 0]))
            log(f"validation: {path.name}: median RGB SWD x uniform {scores[str(path)]:.3f}")
    return scores
