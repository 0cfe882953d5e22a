r"""In-scattered radiance ``Ls`` on the density grid (paper, Eq. 10).

Under a constant environment of radiance ``Le`` and an isotropic phase function, single scattering
at a point ``x`` receives

.. math::  L_s(x) = \frac{L_e}{K} \sum_{k=1}^{K} \mathrm{Tr}(x_{b,k} \to x),
           \qquad \mathrm{Tr} = \exp\Big(-\int_0^{s_b} \sigma_t(x + s\,\omega_k)\,ds\Big),

with ``K`` Hammersley directions ``omega_k`` on the sphere and ``x_{b,k}`` the point where the ray
from ``x`` along ``omega_k`` leaves the medium box. Ls does not depend on the albedo, so it is
computed once per density, at the voxel centres, for ``Le = 1`` (the layer scales it by the
scene's environment radiance).

Two methods, both Dr.Jit kernels in the active Mitsuba variant:

``bruteforce``
    For every voxel and direction, march ``steps`` midpoint samples of the trilinear ``sigma_t`` to
    the box boundary: ``X*Y*Z*K*steps`` trilinear lookups (64^3 x 128 x 64: about 2.1e9).

``sheared`` (default)
    Per direction, let ``a`` be its dominant axis and call the voxel-centre planes across ``a``
    slices. Lines parallel to ``omega_k`` start on a regular lattice (spacing one voxel) at the
    light-side face and are marched slice by slice; on a slice plane trilinear interpolation is
    bilinear, and the optical depth accumulates with the trapezoid rule over segments of length
    ``h / |omega_a|``. The lines see the density extended sideways by its edge values, so their
    optical depth is smooth across the box's side faces. A voxel centre lies on its own slice,
    inside a cell of the lattice; its line toward the light leaves the box at slice position
    ``mu`` (the light-side face, or a side face for grazing directions), and its optical depth
    is ``tau(m) - tau(mu)``, both read from the 4x4 surrounding lines by Catmull-Rom interpolation.
    This is shear-warp resampling: about ``1-4 * X*Y*Z*K`` bilinear lookups for the lines
    (their lattice is wider than the box for oblique directions) and ``24 * X*Y*Z*K`` gathers.
    Directions are processed in batches, each one Dr.Jit kernel for the lines and one for the
    voxels, with a line buffer small enough to stay in cache.

Directions with zero components (Hammersley's first point has one) are safe in both methods: the
boundary distance treats a zero component as "never leaves through that pair of faces", and the
sheared method only ever divides by the dominant component.
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np

from ..scenes.box import MediumBox

METHODS = ("sheared", "bruteforce")
MAX_BUFFER_FLOATS = 1 << 22  # optical-depth buffer per batch of directions (16 MB: stays in cache)


def hammersley_sphere(count: int) -> np.ndarray:
    """``count`` Hammersley points on the unit sphere, shape ``(count, 3)``, ``(x, y, z)``.

    Uniform in ``cos(theta) = 1 - 2 (i + 1/2) / count`` and ``phi = 2 pi * radical_inverse_2(i)``, so
    the set is equal-area stratified and the poles themselves are never drawn.
    """
    if count < 1:
        raise ValueError(f"Need at least one direction, got {count}.")
    index = np.arange(count, dtype=np.uint64)
    bits = index.copy()
    radical = np.zeros(count, dtype=np.float64)
    scale = 0.5
    while bits.any():
        radical += (bits & 1).astype(np.float64) * scale
        bits >>= np.uint64(1)
        scale *= 0.5
    cos_theta = 1.0 - 2.0 * (index.astype(np.float64) + 0.5) / count
    sin_theta = np.sqrt(np.maximum(0.0, 1.0 - cos_theta**2))
    phi = 2.0 * math.pi * radical
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta], axis=-1)


def inscattered_radiance(
    sigma_t: np.ndarray, directions: int = 128, method: str = "sheared", steps: int = 64
) -> np.ndarray:
    """Ls for unit environment radiance at every voxel centre.

    Args:
        sigma_t: extinction ``(Z, Y, X)`` in 1/world-length, the box of ``MediumBox(sigma_t.shape)``.
        directions: K, the number of Hammersley directions.
        method: ``"sheared"`` (fast, default) or ``"bruteforce"`` (reference).
        steps: marching steps per direction for ``"bruteforce"``.

    Returns:
        ``(Z, Y, X)`` float32 array with values in ``(0, 1]``.
    """
    if method not in METHODS:
        raise ValueError(f"Unknown Ls method {method!r}; choose one of {METHODS}.")
    sigma_t = np.ascontiguousarray(sigma_t, dtype=np.float32)
    if sigma_t.ndim != 3:
        raise ValueError(f"sigma_t must be (Z, Y, X), got shape {sigma_t.shape}.")
    box = MediumBox(sigma_t.shape)
    texture = mi.Texture3f(mi.TensorXf(sigma_t[..., None]))
    omegas = hammersley_sphere(directions)
    if method == "bruteforce":
        ls = _bruteforce(texture, box, omegas, steps)
    else:
        ls = _sheared(texture, box, omegas)
    return np.asarray(ls, dtype=np.float32).reshape(sigma_t.shape)


def _voxel_centre_positions(box: MediumBox):
    """Voxel-unit positions ``(x+1/2, y+1/2, z+1/2)`` of all voxels, in ``arr.ravel()`` order."""
    z_res, y_res, x_res = box.shape_zyx
    index = dr.arange(mi.UInt32, x_res * y_res * z_res)
    x = index % x_res
    y = (index // x_res) % y_res
    z = index // (x_res * y_res)
    return mi.Point3f(mi.Float(x) + 0.5, mi.Float(y) + 0.5, mi.Float(z) + 0.5)


def _bruteforce(texture, box: MediumBox, omegas: np.ndarray, steps: int):
    omega_table = mi.Vector3f(*(mi.Float(omegas[:, i]) for i in range(3)))
    visibility = _march_bruteforce(
        texture, mi.ScalarVector3f(box.resolution_xyz), box.voxel_size, _voxel_centre_positions(box),
        omega_table, len(omegas), steps,
    )
    return visibility.numpy()


@dr.syntax
def _march_bruteforce(texture, res, h: float, q, omega_table, count: int, steps: int):
    visibility = dr.zeros(mi.Float, dr.width(q))
    k = mi.UInt32(0)
    while k < count:
        omega = dr.gather(mi.Vector3f, omega_table, k)
        # Distance to the box boundary in voxel units; zero components never reach a face.
        t_face = dr.select(omega > 0, (res - q) / omega, dr.select(omega < 0, -q / omega, dr.inf))
        dt = dr.min(t_face) / steps
        tau = mi.Float(0.0)
        j = mi.UInt32(0)
        while j < steps:
            p = q + omega * ((mi.Float(j) + 0.5) * dt)
            tau += texture.eval(p / res)[0]
            j += 1
        visibility += dr.exp(-tau * dt * h)
        k += 1
    return visibility / count


def _sheared(texture, box: MediumBox, omegas: np.ndarray):
    """Sheared sweep over all directions, in batches that bound the line buffer's memory."""
    res_np = box.resolution_xyz
    plans = [_line_plan(omega, res_np, box.voxel_size) for omega in omegas]
    q = _voxel_centre_positions(box)
    visibility = dr.zeros(mi.Float, dr.width(q))
    batch: list[dict] = []
    for plan in plans:
        if batch and sum(p["lines"] * p["slices"] for p in batch + [plan]) > MAX_BUFFER_FLOATS:
            visibility = _sheared_batch(texture, res_np, q, visibility, batch)
            batch = []
        batch.append(plan)
    visibility = _sheared_batch(texture, res_np, q, visibility, batch)
    return (visibility / len(omegas)).numpy()


def _line_plan(omega: np.ndarray, res: np.ndarray, voxel_size: float) -> dict:
    """Geometry of one direction's lattice of lines (all lengths in voxel units).

    ``a`` is the dominant axis of ``omega``; slices are the voxel-centre planes across it, counted
    by ``m`` from the light side. Line ``(jb, jc)`` passes through
    ``origin + jb e_b + jc e_c - m * step`` at slice ``m``; ``step`` moves one slice toward the light.
    """
    a = int(np.argmax(np.abs(omega)))
    b, c = [axis for axis in range(3) if axis != a]
    slices = int(res[a])
    step = omega / abs(omega[a])
    span_b, span_c = (slices - 1) * step[b], (slices - 1) * step[c]
    origin = np.zeros(3)
    origin[a] = slices - 0.5 if omega[a] > 0 else 0.5
    # One extra line on each side feeds the outer taps of the cubic interpolation.
    origin[b] = math.floor(min(0.0, span_b)) - 0.5
    origin[c] = math.floor(min(0.0, span_c)) - 0.5
    lines_b = int(res[b]) + math.ceil(abs(span_b)) + 3
    lines_c = int(res[c]) + math.ceil(abs(span_c)) + 3
    eye = np.eye(3)
    return {
        "origin": origin, "e_a": eye[a], "e_b": eye[b], "e_c": eye[c], "step": step,
        "lines_c": lines_c, "lines": lines_b * lines_c, "slices": slices,
        "first": float(slices - 1) if omega[a] > 0 else 0.0, "stride": -1.0 if omega[a] > 0 else 1.0,
        "segment": voxel_size / abs(omega[a]),  # world length between consecutive slices
    }


def _sheared_batch(texture, res_np, q, visibility, plans: list[dict]):
    def table(key, kind=mi.Float):
        values = np.array([p[key] for p in plans])
        if values.ndim == 2:
            return mi.Vector3f(*(mi.Float(values[:, i]) for i in range(3)))
        return kind(values)

    lines = np.array([p["lines"] for p in plans], dtype=np.int64)
    buffer_offset = np.concatenate([[0], np.cumsum(lines * [p["slices"] for p in plans])[:-1]])
    line_offset = np.concatenate([[0], np.cumsum(lines)[:-1]])
    direction_of_line = np.repeat(np.arange(len(plans)), lines)
    local_line = np.arange(lines.sum()) - line_offset[direction_of_line]
    lines_c = np.array([p["lines_c"] for p in plans])[direction_of_line]
    tables = {
        key: table(key) for key in ("origin", "e_a", "e_b", "e_c", "step", "first", "stride", "segment")
    }
    tables["lines_c"] = table("lines_c", mi.UInt32)
    tables["slices"] = table("slices", mi.UInt32)
    tables["buffer_offset"] = mi.UInt32(buffer_offset)
    res = mi.ScalarVector3f(res_np)

    tau_lines = dr.empty(mi.Float, int(buffer_offset[-1] + lines[-1] * plans[-1]["slices"]))
    _march_lines(
        texture, res, tables, mi.UInt32(direction_of_line), mi.UInt32(local_line),
        mi.Float(local_line // lines_c), mi.Float(local_line % lines_c), tau_lines,
    )
    visibility = _gather_visibility(visibility, tau_lines, q, res, tables, dr.opaque(mi.UInt32, len(plans)))
    dr.eval(visibility)
    return visibility


def _direction(tables, k):
    """The per-direction constants of ``_line_plan`` for direction index ``k`` (per lane)."""
    return {key: dr.gather(type(value), value, k) for key, value in tables.items()}


@dr.syntax
def _march_lines(texture, res, tables, direction_of_line, local_line, jb, jc, tau_lines):
    """Optical depth from the light-side face to each slice, for every line of every direction.

    Lines run through the density extended sideways by its edge values (the texture's clamp
    mode); the gather only ever takes differences of tau over a voxel's in-box stretch. The
    trapezoid rule samples the light-side face and then every slice crossing (finer sampling
    along the lines was measured not to help: the error is in the interpolation between lines).
    Writes ``tau_lines[buffer_offset + line * slices + m]``.
    """
    d = _direction(tables, direction_of_line)
    face = d["origin"] + d["e_b"] * jb + d["e_c"] * jc + 0.5 * d["step"]
    target = d["buffer_offset"] + local_line * d["slices"]
    tau = mi.Float(0.0)
    sigma_prev = texture.eval(face / res)[0]
    m = mi.UInt32(0)
    while m < d["slices"]:
        sigma = texture.eval((face - d["step"] * (mi.Float(m) + 0.5)) / res)[0]
        tau += 0.5 * (sigma_prev + sigma) * dr.select(m == 0, 0.5, 1.0) * d["segment"]
        dr.scatter(tau_lines, tau, target + m)
        sigma_prev = sigma
        m += 1


def _catmull_rom_weights(t):
    """Weights of the four taps at -1, 0, 1, 2 for Catmull-Rom interpolation at t in [0, 1)."""
    t2, t3 = t * t, t * t * t
    return (
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    )


@dr.syntax
def _gather_visibility(visibility, tau_lines, q, res, tables, count):
    """Add exp(-tau) at every voxel centre, for each direction, from the lines around its own line.

    The voxel's line toward the light leaves the box either through the light-side face (half a
    slice beyond slice 0) or through a side face, at slice position ``mu`` >= -1/2. Its optical depth
    is ``tau(m) - tau(mu)`` on the sideways-extended lines: those are smooth across the side faces,
    so interpolation between lines stays accurate next to the faces, where the in-box optical
    depth of grazing directions changes by a whole chord within one voxel. Between lines the
    optical depth is interpolated bicubically (Catmull-Rom); bilinear weights leave ~4x the error.
    """
    k = mi.UInt32(0)
    while k < count:
        d = _direction(tables, k)
        m = d["first"] + d["stride"] * (dr.dot(q, d["e_a"]) - 0.5)
        q_b, q_c = dr.dot(q, d["e_b"]), dr.dot(q, d["e_c"])
        step_b, step_c = dr.dot(d["step"], d["e_b"]), dr.dot(d["step"], d["e_c"])
        xi_b = q_b - dr.dot(d["origin"], d["e_b"]) + m * step_b
        xi_c = q_c - dr.dot(d["origin"], d["e_c"]) + m * step_c
        jb, jc = dr.floor(xi_b), dr.floor(xi_c)
        fb, fc = xi_b - jb, xi_c - jc
        wb, wc = _catmull_rom_weights(fb), _catmull_rom_weights(fc)
        corner = d["buffer_offset"] + ((mi.UInt32(jb) - 1) * d["lines_c"] + (mi.UInt32(jc) - 1)) * d["slices"]

        # Slices travelled toward the light before leaving the box (step is +-1 on the slice axis).
        to_side_b = dr.select(step_b > 0, (dr.dot(res, d["e_b"]) - q_b) / step_b, dr.select(step_b < 0, -q_b / step_b, dr.inf))
        to_side_c = dr.select(step_c > 0, (dr.dot(res, d["e_c"]) - q_c) / step_c, dr.select(step_c < 0, -q_c / step_c, dr.inf))
        m = dr.round(m)
        exit_position = m - dr.minimum(m + 0.5, dr.minimum(to_side_b, to_side_c))  # in [-1/2, m]
        below = dr.maximum(dr.floor(exit_position), 0.0)
        above = dr.minimum(below + 1.0, m)
        fraction = dr.clip(exit_position - below, 0.0, 1.0)
        leaves_by_side = exit_position > -0.5

        tau_here, tau_below, tau_above = mi.Float(0.0), mi.Float(0.0), mi.Float(0.0)
        for db in range(4):
            for dc in range(4):
                line = corner + (db * d["lines_c"] + dc) * d["slices"]
                tau_here += wb[db] * wc[dc] * dr.gather(mi.Float, tau_lines, line + mi.UInt32(m))
                if db in (1, 2) and dc in (1, 2):
                    # The exit term is small next to tau_here: bilinear is enough there.
                    weight = dr.select(db == 1, 1.0 - fb, fb) * dr.select(dc == 1, 1.0 - fc, fc)
                    tau_below += weight * dr.gather(mi.Float, tau_lines, line + mi.UInt32(below), leaves_by_side)
                    tau_above += weight * dr.gather(mi.Float, tau_lines, line + mi.UInt32(above), leaves_by_side)
        tau_exit = dr.select(
            exit_position < 0.0,
            tau_below * (exit_position + 0.5) / 0.5,  # first half slice: tau grows from 0 at the face
            dr.lerp(tau_below, tau_above, fraction),
        )
        visibility += dr.exp(-dr.maximum(tau_here - tau_exit, 0.0))
        k += 1
    return visibility
