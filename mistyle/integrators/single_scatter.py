r"""The fast volume rendering layer as a Mitsuba integrator (paper, Sec. 4.3).

.. _integrator-mistyle_single_scatter:

Single-scattering ray marcher (:monosp:`mistyle_single_scatter`)
-----------------------------------------------------------------

.. pluginparameters::

 * - sigma_t
   - |tensor|
   - Extinction :math:`\sigma_t` on the grid, ``(Z, Y, X, 1)``, in 1/world-length.
 * - ls
   - |tensor|
   - In-scattered radiance :math:`L_s` for unit environment radiance, ``(Z, Y, X, 1)``: the nodes
     of its trilinear interpolation (``mistyle.integrators.inscatter.trilinear_nodes``), on the
     density's grid or a whole multiple of it.
 * - albedo
   - |tensor|
   - Single-scattering albedo :math:`\alpha`, ``(Z, Y, X, 3)``, RGB in [0, 1].
     *(differentiable)*
 * - albedo_min, albedo_max
   - |point|
   - The part of the grid the albedo covers, in the box's unit coordinates (a crop of voxels
     ``[a, b)`` of ``N``: ``a / N`` to ``b / N`` per axis, x first); beyond it the albedo repeats its
     faces, as if padded to the whole grid by replication. (Default: 0 to 1, the whole grid)
 * - bbox_min, bbox_max
   - |point|
   - The medium box the grids fill (``mistyle.scenes.box.MediumBox``).
 * - march_min, march_max
   - |point|
   - The part of the medium box that rays are marched through: where the interpolated
     :math:`\sigma_t` can be non-zero (``MediumBox.field_support``). Nothing outside it contributes,
     so the N segments are spent where the medium is. (Default: the medium box)
 * - steps
   - |int|
   - Number N of equal ray-marching segments between the march box's entry and exit. (Default: 64)
 * - scheme
   - |string|
   - Per-segment weight: ``exact`` (default), ``midpoint`` or ``riemann`` (the paper's Eq. 9).
 * - white
   - |bool|
   - Also return, as the AOV channels ``white.R``, ``white.G``, ``white.B``, the same march with a
     white albedo (:math:`\alpha = 1`): the medium's brightness, from which a render's body mask is
     found, for the cost of one more sum. (Default: false)

One ray through each pixel centre (box filter, no jitter) is clipped to the march box and cut into N
segments of length :math:`\Delta t`. At each segment midpoint :math:`x_i` the layer looks up
:math:`\sigma_i`, :math:`L_{s,i}` and :math:`\alpha_i` trilinearly and accumulates

.. math::  L = L_e \sum_{i=1}^{N} w_i\, \alpha_i\, L_{s,i},
           \qquad T_{i} = \exp\Big(-\sum_{j \le i} \sigma_j \Delta t\Big)

with the weight :math:`w_i` of the chosen ``scheme``:

* ``riemann``: :math:`w_i = T_i\, \sigma_i \Delta t` (the paper: transmittance includes sample i);
* ``midpoint``: :math:`w_i = T_{i-1}\, e^{-\sigma_i \Delta t / 2}\, \sigma_i \Delta t`;
* ``exact``: :math:`w_i = T_{i-1}\,(1 - e^{-\sigma_i \Delta t})`, exact for a segment of constant
  :math:`\sigma_i`, :math:`\alpha_i`, :math:`L_{s,i}`.

``exact`` is the default: it converges fastest in N, and against ``volpath`` (max_depth=2, traced
through the same pixel centres; ``experiments/layer_vs_pathtraced.py``, 64^3, N=64, with the
``ls`` nodes of ``prepare_density`` and the march box of ``layer_scene``) it leaves 0.48% relative
RMSE, ``midpoint`` 0.52% and ``riemann`` 6.8%. With the Ls samples themselves in ``ls`` and the
whole box marched, as in the paper, ``exact`` leaves 0.89% (docs/performance.md).

:math:`L_e` is the radiance of the scene's constant environment emitter. The image is linear in
:math:`\alpha`, so the adjoint pass replays the march and scatters :math:`\delta L\, L_e w_i L_{s,i}`
into the eight voxels around :math:`x_i` with their trilinear weights (Eq. 11); nothing is stored
between the two passes. Rays that miss the box return zero and are marked invalid (alpha 0).

.. code-block:: python

    'integrator': {
        'type': 'mistyle_single_scatter',
        'sigma_t': mi.TensorXf(sigma_t[..., None]), 'ls': mi.TensorXf(ls[..., None]),
        'albedo': mi.TensorXf(albedo), 'bbox_min': [-.5, -.5, -.5], 'bbox_max': [.5, .5, .5],
    }

Use ``mistyle.integrators.layer_scene`` rather than writing this dictionary by hand.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from ..conventions import DEFAULT_LAYER_SCHEME as DEFAULT_SCHEME
from ..conventions import LAYER_SCHEMES as SCHEMES

WHITE_AOVS = ("white.R", "white.G", "white.B")


class SingleScatterIntegrator(mi.ad.integrators.common.RBIntegrator):
    def __init__(self, props: mi.Properties):
        super().__init__(props)
        self.steps = int(props.get("steps", 64))
        if self.steps < 1:
            raise ValueError(f"'steps' must be >= 1, got {self.steps}.")
        self.scheme = props.get("scheme", DEFAULT_SCHEME)
        if self.scheme not in SCHEMES:
            raise ValueError(f"Unknown scheme {self.scheme!r}; choose one of {SCHEMES}.")
        self.bbox = mi.ScalarBoundingBox3f(
            mi.ScalarPoint3f(props.get("bbox_min")), mi.ScalarPoint3f(props.get("bbox_max"))
        )
        # Parameters (traversed), so one loaded scene can take another density's support.
        self.march_min = mi.Point3f(mi.ScalarPoint3f(props.get("march_min", self.bbox.min)))
        self.march_max = mi.Point3f(mi.ScalarPoint3f(props.get("march_max", self.bbox.max)))
        self._check_march_box()
        self.sigma_t = mi.Texture3f(_grid(props, "sigma_t", 1))
        self.ls = mi.Texture3f(_grid(props, "ls", 1))
        self.albedo = mi.Texture3f(_grid(props, "albedo", 3))
        # The part of the box the albedo grid covers, in the box's unit coordinates (default: all of it).
        # Beyond it the texture's clamped lookups repeat its faces, as if it were padded to the whole grid.
        self.albedo_min = mi.Point3f(mi.ScalarPoint3f(props.get("albedo_min", mi.ScalarPoint3f(0.0))))
        self.albedo_max = mi.Point3f(mi.ScalarPoint3f(props.get("albedo_max", mi.ScalarPoint3f(1.0))))
        self.white = bool(props.get("white", False))

    def traverse(self, callback):
        callback.put("albedo", self.albedo.tensor(), mi.ParamFlags.Differentiable)
        callback.put("sigma_t", self.sigma_t.tensor(), mi.ParamFlags.NonDifferentiable)
        callback.put("ls", self.ls.tensor(), mi.ParamFlags.NonDifferentiable)
        callback.put("march_min", self.march_min, mi.ParamFlags.NonDifferentiable)
        callback.put("march_max", self.march_max, mi.ParamFlags.NonDifferentiable)
        callback.put("albedo_min", self.albedo_min, mi.ParamFlags.NonDifferentiable)
        callback.put("albedo_max", self.albedo_max, mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys):
        for key in keys:
            if key in ("albedo", "sigma_t", "ls"):
                # SceneParameters wrote into the texture's own tensor; let the texture pick it up.
                getattr(self, key).update_inplace()
        if "march_min" in keys or "march_max" in keys:
            self._check_march_box()

    def _check_march_box(self):
        corners = [mi.ScalarPoint3f(*(float(c[0]) for c in corner)) for corner in (self.march_min, self.march_max)]
        if not all(self.bbox.contains(corner) for corner in corners):
            raise ValueError("march_min/march_max must lie inside the medium box bbox_min/bbox_max.")

    def aov_names(self):
        return list(WHITE_AOVS) if self.white else []

    def render_backward(self, scene, params, grad_in, sensor=0, seed=0, spp=0):
        """The adjoint pass of ``render``. The white AOVs do not depend on α, so their channels of
        ``grad_in`` are dropped and the pass runs without them (Mitsuba's ``RBIntegrator`` cannot splat
        AOVs in its adjoint pass: it weighs them by a spectrum)."""
        if not self.white:
            return super().render_backward(scene, params, grad_in, sensor, seed, spp)
        self.white = False
        try:
            return super().render_backward(scene, params, grad_in[:, :, :3], sensor, seed, spp)
        finally:
            self.white = True

    def sample_rays(self, scene, sensor, sampler):
        """One ray through each pixel centre; the sampler is not consumed."""
        ray, weight, pixel = pixel_centre_rays(sensor, sampler.sample_count())
        return ray, weight, pixel + mi.Vector2f(sensor.film().crop_offset())

    @dr.syntax
    def sample(self, mode, scene, sampler, ray, δL, state_in, active, **kwargs):
        primal = mode == dr.ADMode.Primal

        # --------------------- Clip the ray to the march box ----------------------
        hit, t_enter, t_exit = mi.BoundingBox3f(self.march_min, self.march_max).ray_intersect(ray)
        t_enter = dr.maximum(t_enter, 0.0)
        active = mi.Bool(active) & hit & (t_exit > t_enter)
        Δt = dr.select(active, (t_exit - t_enter) / self.steps, 0.0)
        origin_unit = (ray.o - self.bbox.min) / self.bbox.extents()
        direction_unit = ray.d / self.bbox.extents()
        Le = self._environment_radiance(scene)
        δα_texture = None
        if dr.hint(mode == dr.ADMode.Forward, mode="scalar"):
            # L is linear in α, so its tangent is the march of the tangent δα. The texture holds its
            # own copy of the parameter tensor, an AD edge the loop's scope cannot cross; take δα
            # here, outside the loop, and look it up like α.
            with dr.resume_grad():
                δα = dr.forward_to(self.albedo.tensor())
            δα_texture = mi.Texture3f(mi.TensorXf(dr.detach(δα)))

        # ------------------------------ Loop state ------------------------------
        L = mi.Spectrum(0.0)
        white = mi.Spectrum(0.0)
        δL = mi.Spectrum(δL if δL is not None else 0.0)
        T = mi.Float(1.0)
        i = mi.UInt32(0)

        while dr.hint(active, label=f"mistyle_single_scatter ({mode.name})"):
            t = t_enter + (mi.Float(i) + 0.5) * Δt
            p = dr.fma(direction_unit, t, origin_unit)
            σ = self.sigma_t.eval(p)[0]
            τ = σ * Δt
            T_next = T * dr.exp(-τ)
            if dr.hint(self.scheme == "riemann", mode="scalar"):
                w = T_next * τ
            elif dr.hint(self.scheme == "midpoint", mode="scalar"):
                w = T * dr.exp(-0.5 * τ) * τ
            else:
                w = T - T_next
            β = Le * (w * self.ls.eval(p)[0])

            # --------------- Differentiable part: the albedo lookup ---------------
            p_albedo = (p - self.albedo_min) / (self.albedo_max - self.albedo_min)
            if dr.hint(mode == dr.ADMode.Forward, mode="scalar"):
                δα = δα_texture.eval(p_albedo)
                δL += β * mi.Spectrum(δα[0], δα[1], δα[2])
            else:
                with dr.resume_grad(when=not primal):
                    α = self.albedo.eval(p_albedo)
                    contribution = β * mi.Spectrum(α[0], α[1], α[2])
                    if dr.hint(primal, mode="scalar"):
                        L += contribution
                        if dr.hint(self.white, mode="scalar"):
                            white += β  # the same sum with α = 1: a white render's pixels, up to rounding
                    else:
                        dr.backward_from(δL * contribution)

            T = T_next
            i += 1
            active &= i < self.steps

        aovs = [white[0], white[1], white[2]] if self.white and primal else []
        return (L if primal else δL), hit, aovs, L

    def _environment_radiance(self, scene) -> mi.Spectrum:
        environment = scene.environment()
        if environment is None:
            raise ValueError(
                "mistyle_single_scatter needs a constant environment emitter in the scene "
                "(use mistyle.integrators.layer_scene)."
            )
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(0.0, 0.0, 1.0)
        return environment.eval(si)

    def to_string(self):
        shape = self.albedo.tensor().shape
        return f"SingleScatterIntegrator[grid={shape[:3]}, steps={self.steps}, scheme={self.scheme!r}]"


def pixel_centre_rays(sensor: mi.Sensor, rays_per_pixel: int = 1):
    """Rays through the centre of every pixel of ``sensor``'s film, ``rays_per_pixel`` copies each.

    Returns ``(ray, weight, pixel)`` with ``pixel`` the integer pixel position (``mi.Vector2f``),
    pixels in row-major order and copies adjacent.
    """
    size = sensor.film().crop_size()
    index = dr.arange(mi.UInt32, dr.prod(size) * rays_per_pixel)
    index //= dr.opaque(mi.UInt32, rays_per_pixel)
    pixel = mi.Vector2u(index % size[0], index // size[0])
    position = (mi.Vector2f(pixel) + 0.5) / mi.ScalarVector2f(size)
    with dr.resume_grad():
        ray, weight = sensor.sample_ray_differential(
            time=sensor.shutter_open(), sample1=0.0, sample2=position, sample3=mi.Point2f(0.5)
        )
    return ray, weight, mi.Vector2f(pixel)


def _grid(props: mi.Properties, name: str, channels: int) -> mi.TensorXf:
    if name not in props:
        raise ValueError(f"mistyle_single_scatter needs the '{name}' grid, a TensorXf (Z, Y, X, {channels}).")
    tensor = mi.TensorXf(props[name])
    if len(tensor.shape) != 4 or tensor.shape[3] != channels:
        raise ValueError(f"'{name}' must be a (Z, Y, X, {channels}) tensor, got shape {tensor.shape}.")
    return tensor


mi.register_integrator("mistyle_single_scatter", lambda props: SingleScatterIntegrator(props))
