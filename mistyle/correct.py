"""Bringing path-traced renders back to the style: the network is trained under single scattering.

The path tracer adds multiple scattering, which brightens and desaturates a medium relative to
the fast layer the network was trained through. ``calibrate_albedo`` undoes this to first order,
per density: render the density with uniform albedo ``a`` at a few levels with ``volpath``
(multiple scattering) to measure the mean foreground radiance ``g(a)``; the fast layer's is
``a * h`` (linear in albedo). Each albedo value ``a`` is then replaced, per channel, by
``g^{-1}(a * h)``: the albedo whose multiply-scattered brightness equals the single-scattered
brightness the network aimed for. ``g`` is monotone, so the inverse is a table lookup.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scenes.builder import DEFAULT_ENV_RADIANCE

LEVELS = (0.1, 0.25, 0.4, 0.55, 0.7, 0.85, 1.0)


@dataclass
class ScatteringCalibration:
    levels: np.ndarray  # albedo levels a, increasing, starting with 0
    multiple: np.ndarray  # g(a): mean path-traced foreground radiance at uniform albedo a
    single: float  # h: mean fast-layer foreground radiance at uniform albedo 1
    seconds: float

    def apply(self, albedo: np.ndarray) -> np.ndarray:
        """``(..., 3)`` albedo -> calibrated albedo (same shape), ``g^{-1}(a h)`` per value."""
        target = np.asarray(albedo, dtype=np.float64) * self.single
        return np.clip(np.interp(target, self.multiple, self.levels), 0.0, 1.0).astype(np.float32)

    def as_dict(self) -> dict:
        return {"levels": self.levels.tolist(), "multiple": self.multiple.tolist(), "single": self.single,
                "seconds": self.seconds}


def measure_calibration(density: np.ndarray, density_scale: float, radiance: float, views, res: int = 64,
                        spp: int = 32, levels=LEVELS, prepared=None) -> ScatteringCalibration:
    """Measure ``g(a)`` and ``h`` for ``density`` under the constant environment ``radiance`` from ``views``.

    ``prepared``: the density's ``PreparedDensity`` when the caller has computed its Ls already.
    """
    import time

    import torch

    from .backend import active_variant
    from .bridge_torch import render_views
    from .scenes import prepare_density
    from .scenes.final import LightSpec, final_scene

    mi = active_variant()
    started = time.perf_counter()
    shape = density.shape
    if prepared is None:
        prepared = prepare_density(density, density_scale)
    with torch.no_grad():
        layer = render_views(torch.ones((3,) + shape), prepared, views, res, radiance=radiance).numpy()
    mask = layer.max(axis=1) > 1e-3  # (V, H, W)
    if not mask.any():
        raise ValueError("The medium is not visible from the calibration views.")
    single = float(layer.transpose(0, 2, 3, 1)[mask].mean())
    # One scene; only the uniform albedo changes between levels.
    scene = mi.load_dict(final_scene(density, density_scale, np.zeros(shape + (3,), np.float32), views, res, res, spp=spp,
                                     light=LightSpec("constant", radiance), seed=17))
    params = mi.traverse(scene)
    albedo_key = next(key for key in params.keys() if key.endswith("interior_medium.albedo.data"))
    multiple = [0.0]
    for level in levels:
        params[albedo_key] = mi.TensorXf(np.full(shape + (3,), level, np.float32))
        params.update()
        images = np.stack([np.array(mi.render(scene, sensor=index), dtype=np.float32) for index in range(len(views))])
        multiple.append(float(images[mask].mean()))
    multiple = np.maximum.accumulate(np.array(multiple))  # monotone despite noise
    return ScatteringCalibration(np.array((0.0,) + tuple(levels)), multiple, single, time.perf_counter() - started)


def refine_albedo(density: np.ndarray, density_scale: float, albedo: np.ndarray, style: np.ndarray, objective,
                  steps: int = 16, views_per_step: int = 2, res: int = 64, spp: int = 8,
                  radiance: float = DEFAULT_ENV_RADIANCE,
                  camera_distance: float = 2.5, lr: float = 0.05, tv_weight: float = 10.0, seed: int = 0,
                  progress=None) -> tuple[np.ndarray, float]:
    """A few Adam steps on the albedo against the style with the path tracer in the loop.

    Mitsuba's ``prbvolpath`` (multiple scattering, constant training light) renders random views on
    the orbit; ``dr.wrap`` carries its albedo gradient to torch, where ``objective`` (the training
    style loss on tone-mapped images) and 3D TV are evaluated. Starts from ``albedo (Z, Y, X, 3)``;
    returns ``(refined albedo, seconds)``.
    """
    import time

    import drjit as dr
    import torch

    from .backend import active_variant
    from .scenes import CameraPath
    from .scenes.final import LightSpec, final_scene
    from .train.losses import tv_loss

    mi = active_variant()
    started = time.perf_counter()
    orbit, rng = CameraPath(distance=camera_distance), np.random.default_rng(seed)
    scene_dict = final_scene(density, density_scale, albedo, [orbit.view(0.0)], res, res, spp=spp,
                             light=LightSpec("constant", radiance))
    scene_dict["integrator"] = {"type": "prbvolpath", "max_depth": -1, "hide_emitters": True}
    scene = mi.load_dict(scene_dict)
    params = mi.traverse(scene)
    albedo_key = next(key for key in params.keys() if key.endswith("interior_medium.albedo.data"))
    camera_key = "sensor000.to_world"

    @dr.wrap(source="torch", target="drjit")
    def path_traced(grid, render_seed):
        params[albedo_key] = grid
        params.update()
        return mi.render(scene, params, sensor=0, spp=spp, seed=render_seed)

    logits = torch.logit(torch.from_numpy(np.asarray(albedo, np.float32)).clamp(1e-3, 1 - 1e-3)).requires_grad_(True)
    optimizer = torch.optim.Adam([logits], lr=lr)
    targets = objective.targets(torch.from_numpy(np.ascontiguousarray(style)).permute(2, 0, 1)[None])
    for step in range(steps):
        grid = torch.sigmoid(logits)
        images = []
        for index in range(views_per_step):
            view = orbit.view(float(rng.random()))
            params[camera_key] = mi.ScalarTransform4f().look_at(origin=view.origin, target=view.target, up=view.up)
            images.append(path_traced(grid, step * views_per_step + index).permute(2, 0, 1))
        loss = objective.loss(torch.stack(images)[None], targets) + tv_weight * tv_loss(grid.permute(3, 0, 1, 2)[None])
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        if progress is not None:
            progress(step + 1, steps, float(loss.detach()))
    return torch.sigmoid(logits).detach().numpy(), time.perf_counter() - started
