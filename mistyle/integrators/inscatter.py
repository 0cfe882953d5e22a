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
    The Hammersley set is mirrored (see ``hammersley_sphere``), so directions come in antipodal
    pairs, and one family of lines serves both. Per pair, let ``a`` be the dominant axis and call
    the voxel-centre planes across ``a`` slices. Lines parallel to ``omega`` start on a regular
    lattice (spacing one voxel) at one face and are marched slice by slice to the other; on a
    slice plane trilinear interpolation is bilinear, and the optical depth from the near face
    accumulates with the trapezoid rule over segments of length ``h / |omega_a|``. The lines see
    the density extended sideways by its edge values, so their optical depth is smooth across the
    box's side faces. Each voxel centre lies on its own slice inside a cell of the lattice; along
    its own line it leaves the box toward either face (or through a side face, for grazing
    directions), and the two optical depths are differences of the lines' cumulative depths,
    interpolated between lines (Catmull-Rom for the long stretches, bilinear for the short ones).
    This is shear-warp resampling: about ``1-4 * X*Y*Z*K/2`` bilinear lookups for the lines and
    ``24 * X*Y*Z*K`` gathers. Directions are processed in batches, each one Dr.Jit kernel for the
    lines and one for the voxels, with a line buffer small enough to stay in cache, and only
    voxels where the layer can use Ls are computed (see ``inscattered_radiance``).

Directions with zero components (Hammersley's first point has one) are safe in both methods: the
boundary distance treats a zero component as "never leaves through that pair of faces", and the
sheared method only ever divides by the dominant component.
"""

from __future__ import annotations

import functools
import math

import drjit as dr
import mitsuba as mi
import numpy as np

from ..backend import lanes
from ..conventions import LS_DIRECTIONS
from ..scenes.box import MediumBox

METHODS = ("sheared", "bruteforce")
FIT_OVERSAMPLE = 3  # fit points per voxel and axis in ``trilinear_nodes``
MAX_BUFFER_FLOATS = 1 << 22  # optical-depth buffer per batch of directions (16 MB: stays in cache)


def hammersley_sphere(count: int) -> np.ndarray:
    """``count`` Hammersley directions on the unit sphere, shape ``(count, 3)``, ``(x, y, z)``.

    The first half is a Hammersley set on the upper hemisphere, uniform in
    ``cos(theta) = 1 - (i + 1/2) / (count / 2)`` and ``phi = 2 pi * radical_inverse_2(i)`` (equal-area
    stratified, poles never drawn); the second half are their antipodes. The mirrored set sums to
    exactly zero, and the sheared sweep serves each direction and its antipode with one set of lines.
    """
    if count < 2 or count % 2:
        raise ValueError(f"The number of directions must be even and >= 2, got {count}.")
    half = count // 2
    index = np.arange(half, dtype=np.uint64)
    bits = index.copy()
    radical = np.zeros(half, dtype=np.float64)
    scale = 0.5
    while bits.any():
        radical += (bits & 1).astype(np.float64) * scale
        bits >>= np.uint64(1)
        scale *= 0.5
    cos_theta = 1.0 - (index.astype(np.float64) + 0.5) / half
    sin_theta = np.sqrt(np.maximum(0.0, 1.0 - cos_theta**2))
    phi = 2.0 * math.pi * radical
    upper = np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), cos_theta], axis=-1)
    return np.concatenate([upper, -upper])


def inscattered_radiance(
    sigma_t: np.ndarray,
    directions: int = LS_DIRECTIONS,
    method: str = "sheared",
    steps: int = 64,
    only_where_used: bool = True,
    grid_factor: int = 1,
) -> np.ndarray:
    """Ls for unit environment radiance at the voxel centres, or on a ``grid_factor`` times finer grid.

    The layer weighs Ls by the extinction interpolated from the same eight voxels, so Ls only
    matters at voxels within one voxel (3x3x3) of non-zero density. With ``only_where_used``
    (default) it is computed there and set to 1 (unshadowed) elsewhere; smoke is mostly empty
    space, so this skips most of the work. Images of the layer do not change.

    Args:
        sigma_t: extinction ``(Z, Y, X)`` in 1/world-length, the box of ``MediumBox(sigma_t.shape)``.
        directions: K, the number of Hammersley directions (even).
        method: ``"sheared"`` (fast, default) or ``"bruteforce"`` (reference).
        steps: marching steps per direction for ``"bruteforce"``.
        only_where_used: compute Ls only where the layer can use it.
        grid_factor: Ls on a grid this many times finer than ``sigma_t``'s (same box), computed
            from the trilinear extinction resampled at its voxel centres. Trilinear interpolation
            of Ls between the density's own voxel centres overestimates it where it is convex (just
            inside the medium's surface); a finer Ls grid is where the layer's error budget says
            the cost should go (``experiments/layer_error_budget.py``).

    Returns:
        ``(Z, Y, X) * grid_factor`` float32 array with values in ``(0, 1]``.
    """
    if method not in METHODS:
        raise ValueError(f"Unknown Ls method {method!r}; choose one of {METHODS}.")
    sigma_t = np.ascontiguousarray(sigma_t, dtype=np.float32)
    if sigma_t.ndim != 3:
        raise ValueError(f"sigma_t must be (Z, Y, X), got shape {sigma_t.shape}.")
    if int(grid_factor) != grid_factor or grid_factor < 1:
        raise ValueError(f"grid_factor must be a positive integer, got {grid_factor!r}.")
    if grid_factor > 1:
        sigma_t = resample_trilinear(sigma_t, int(grid_factor))
    box = MediumBox(sigma_t.shape)
    texture = mi.Texture3f(mi.TensorXf(sigma_t[..., None]))
    omegas = hammersley_sphere(directions)
    used = layer_reads_ls(sigma_t) if only_where_used else np.ones(sigma_t.shape, dtype=bool)
    ls = np.ones(sigma_t.shape, dtype=np.float32)
    if not used.any():
        return ls
    q = _voxel_centre_positions(used)
    if method == "bruteforce":
        values = _bruteforce(texture, box, q, omegas, steps)
    else:
        values = _sheared(texture, box, q, omegas[: directions // 2])
    ls[used] = values
    return ls


def resample_trilinear(grid: np.ndarray, factor: int) -> np.ndarray:
    """``grid (Z, Y, X)`` sampled at the voxel centres of a ``factor`` times finer grid of the same box.

    Uses the texture lookup the layer and the path tracer use (trilinear between voxel centres,
    clamped at the faces), so the finer grid holds exactly the field they render.
    """
    texture = mi.Texture3f(mi.TensorXf(np.ascontiguousarray(grid, dtype=np.float32)[..., None]))
    shape = tuple(n * factor for n in grid.shape)
    z, y, x = (np.arange(n, dtype=np.float32) for n in shape)
    zz, yy, xx = np.meshgrid((z + 0.5) / shape[0], (y + 0.5) / shape[1], (x + 0.5) / shape[2], indexing="ij")
    p = mi.Point3f(lanes(mi.Float, xx), lanes(mi.Float, yy), lanes(mi.Float, zz))
    return np.asarray(texture.eval(p)[0], dtype=np.float32).reshape(shape)


def trilinear_nodes(
    samples: np.ndarray, valid: np.ndarray | None = None, oversample: int = FIT_OVERSAMPLE
) -> np.ndarray:
    """Nodal values whose trilinear interpolant best fits the smooth field sampled at the voxel centres.

    Interpolating point samples of Ls trilinearly overestimates it wherever it is convex (just inside
    the medium's surface), by up to an eighth of its second difference. This returns instead, per
    axis, the least-squares fit of the texture's piecewise-linear, clamped-at-the-ends function to
    the Catmull-Rom cubic through the samples (each tap past the grid's ends is the linear
    extrapolation of the last two; the cubic goes on into the outer half voxels, where Ls keeps
    changing though the texture is flat), taken at ``oversample`` points per voxel: the projection of
    a smooth interpolant onto the layer's basis. It is separable and linear, ``M @ samples`` along
    each axis, with ``M`` an ``(n, n)`` band close to ``(0.004, -0.019, -0.025, 1.08, -0.025, -0.019,
    0.004)`` for ``oversample = 3``; constant fields are unchanged, and linear ones too away from the
    grid's ends. The nodes are coefficients, not Ls values, and may leave ``[0, 1]`` slightly where
    the field bends hardest.

    Args:
        samples: ``(Z, Y, X)`` values at the voxel centres.
        valid: ``(Z, Y, X)`` bool, where ``samples`` hold the field (``inscattered_radiance`` computes
            Ls only near the medium; a 1.0 beyond would read as a cliff). The band then uses only
            valid samples, its weights renormalised to sum to one, and the result keeps ``samples``
            outside ``valid``. ``None``: all valid.
        oversample: fit points per voxel along each axis.

    Returns:
        ``(Z, Y, X)`` float32 nodal values for the layer's ``ls`` texture.
    """
    samples = np.asarray(samples, dtype=np.float32)
    if samples.ndim != 3:
        raise ValueError(f"samples must be (Z, Y, X), got shape {samples.shape}.")

    def fit(grid):
        for axis, n in enumerate(grid.shape):
            matrix = _trilinear_fit_matrix(n, int(oversample)).astype(np.float32)
            grid = np.moveaxis(np.tensordot(matrix, np.moveaxis(grid, axis, 0), axes=1), 0, axis)
        return grid

    if valid is None:
        return np.ascontiguousarray(fit(samples), dtype=np.float32)
    valid = np.asarray(valid, dtype=bool)
    weight = valid.astype(np.float32)
    # A valid voxel's own tap weighs about 1.08 and the others little, so the sum stays near one.
    nodes = fit(samples * weight) / np.where(valid, fit(weight), 1.0)
    return np.ascontiguousarray(np.where(valid, nodes, samples), dtype=np.float32)


@functools.lru_cache(maxsize=16)
def _trilinear_fit_matrix(n: int, oversample: int) -> np.ndarray:
    """``(n, n)``: least-squares linear-interpolation nodes of the Catmull-Rom curve through ``n`` samples."""
    if n < 3:
        return np.eye(n)
    # Fit points at x_j = (j + 1/2)/f - 1/2 in voxel-centre coordinates. The texture lookup clamps them
    # to the outer centres; the field does not stop there (Ls keeps rising toward an open face), so
    # the cubic is extrapolated into the outer half voxels.
    x_field = (np.arange(n * oversample) + 0.5) / oversample - 0.5
    x = np.clip(x_field, 0, n - 1)
    cell = np.minimum(np.floor(x).astype(int), n - 2)
    t = x - cell
    rows = np.arange(x.size)
    linear = np.zeros((x.size, n))
    np.add.at(linear, (rows, cell), 1 - t)
    np.add.at(linear, (rows, cell + 1), t)
    t = x_field - cell
    cubic = np.zeros((x.size, n))
    weights = (
        0.5 * (-(t**3) + 2 * t**2 - t),
        0.5 * (3 * t**3 - 5 * t**2 + 2),
        0.5 * (-3 * t**3 + 4 * t**2 + t),
        0.5 * (t**3 - t**2),
    )
    for offset, weight in zip((-1, 0, 1, 2), weights):
        index = cell + offset  # a tap past either end is the linear extrapolation of the last two samples
        inside = np.clip(index, 0, n - 1)
        beyond = index - inside  # -1, 0 or 1
        np.add.at(cubic, (rows, inside), weight * (1 + np.abs(beyond)))
        np.add.at(cubic, (rows, np.clip(inside - beyond, 0, n - 1)), -weight * np.abs(beyond))
    return np.linalg.solve(linear.T @ linear, linear.T @ cubic)


def inscattered_radiance_at(
    sigma_t: np.ndarray, points: np.ndarray, directions: int = LS_DIRECTIONS, steps: int = 64
) -> np.ndarray:
    """Ls for unit radiance at arbitrary ``points (P, 3)``, given in voxel units ``(x, y, z)``.

    Brute-force marching (the reference); used to study Ls on grids finer than the density's.
    """
    sigma_t = np.ascontiguousarray(sigma_t, dtype=np.float32)
    box = MediumBox(sigma_t.shape)
    texture = mi.Texture3f(mi.TensorXf(sigma_t[..., None]))
    q = mi.Point3f(*(lanes(mi.Float, np.asarray(points, dtype=np.float32)[:, i]) for i in range(3)))
    return np.asarray(_bruteforce(texture, box, q, hammersley_sphere(directions), steps), dtype=np.float32)


def layer_reads_ls(sigma_t: np.ndarray) -> np.ndarray:
    """Voxels whose Ls the layer can read where the extinction is non-zero: those whose 3x3x3
    neighbourhood holds non-zero extinction, ``(Z, Y, X)`` bool."""
    occupied = np.pad(sigma_t > 0, 1)
    used = np.zeros(sigma_t.shape, dtype=bool)
    z, y, x = sigma_t.shape
    for dz in range(3):
        for dy in range(3):
            for dx in range(3):
                used |= occupied[dz : dz + z, dy : dy + y, dx : dx + x]
    return used


def _voxel_centre_positions(selected: np.ndarray):
    """Voxel-unit positions ``(x+1/2, y+1/2, z+1/2)`` of the ``selected`` voxels, in C order."""
    z, y, x = np.nonzero(selected)
    return mi.Point3f(lanes(mi.Float, x + 0.5), lanes(mi.Float, y + 0.5), lanes(mi.Float, z + 0.5))


def _bruteforce(texture, box: MediumBox, q, omegas: np.ndarray, steps: int):
    omega_table = mi.Vector3f(*(lanes(mi.Float, omegas[:, i]) for i in range(3)))
    visibility = _march_bruteforce(
        texture, mi.ScalarVector3f(box.resolution_xyz), box.voxel_size, q, omega_table, len(omegas), steps
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


def _sheared(texture, box: MediumBox, q, primaries: np.ndarray):
    """Mean transmittance over ``primaries`` and their antipodes, by the sheared sweep.

    Directions are processed in batches that bound the line buffer (so it stays in cache), each
    batch one Dr.Jit kernel for the lines and one for the voxels.
    """
    res_np = box.resolution_xyz
    plans = [_line_plan(omega, res_np, box.voxel_size) for omega in primaries]
    visibility = dr.zeros(mi.Float, dr.width(q))
    batch: list[dict] = []
    for plan in plans:
        if batch and sum(p["lines"] * p["samples"] for p in batch + [plan]) > MAX_BUFFER_FLOATS:
            visibility = _sheared_batch(texture, res_np, q, visibility, batch)
            batch = []
        batch.append(plan)
    visibility = _sheared_batch(texture, res_np, q, visibility, batch)
    return (visibility / (2 * len(primaries))).numpy()


def _line_plan(omega: np.ndarray, res: np.ndarray, voxel_size: float) -> dict:
    """Geometry of one direction's lattice of lines (all lengths in voxel units).

    ``a`` is the dominant axis of ``omega``; slices are the voxel-centre planes across it, counted
    by ``m`` from the face that ``omega`` points to (the "near face"). Line ``(jb, jc)`` passes
    through ``origin + jb e_b + jc e_c - m * step`` at slice position ``m``; ``step`` moves one slice
    toward the near face. Each line stores ``samples = slices + 2`` optical depths from the near
    face: at the near face (0), at slices 0 .. slices-1, and at the far face.
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
        "origin": origin,
        "e_a": eye[a],
        "e_b": eye[b],
        "e_c": eye[c],
        "step": step,
        "lines_c": lines_c,
        "lines": lines_b * lines_c,
        "slices": slices,
        "samples": slices + 2,
        "first": float(slices - 1) if omega[a] > 0 else 0.0,
        "stride": -1.0 if omega[a] > 0 else 1.0,
        "segment": voxel_size / abs(omega[a]),  # world length between consecutive slices
    }


def _sheared_batch(texture, res_np, q, visibility, plans: list[dict]):
    def table(key, kind=mi.Float):
        values = np.array([p[key] for p in plans])
        if values.ndim == 2:
            return mi.Vector3f(*(lanes(mi.Float, values[:, i]) for i in range(3)))
        return lanes(kind, values)

    lines = np.array([p["lines"] for p in plans], dtype=np.int64)
    sizes = lines * np.array([p["samples"] for p in plans])
    buffer_offset = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    line_offset = np.concatenate([[0], np.cumsum(lines)[:-1]])
    direction_of_line = np.repeat(np.arange(len(plans)), lines)
    local_line = np.arange(lines.sum()) - line_offset[direction_of_line]
    lines_c = np.array([p["lines_c"] for p in plans])[direction_of_line]
    tables = {key: table(key) for key in ("origin", "e_a", "e_b", "e_c", "step", "first", "stride", "segment")}
    tables["slices"] = table("slices")
    for key in ("lines", "lines_c", "samples"):
        tables[key] = table(key, mi.UInt32)
    tables["buffer_offset"] = lanes(mi.UInt32, buffer_offset)
    res = mi.ScalarVector3f(res_np)

    tau_lines = dr.empty(mi.Float, int(sizes.sum()))
    _march_lines(
        texture,
        res,
        tables,
        lanes(mi.UInt32, direction_of_line),
        lanes(mi.UInt32, local_line),
        lanes(mi.Float, local_line // lines_c),
        lanes(mi.Float, local_line % lines_c),
        tau_lines,
    )
    visibility = _gather_visibility(visibility, tau_lines, q, res, tables, dr.opaque(mi.UInt32, len(plans)))
    dr.eval(visibility)
    return visibility


def _direction(tables, k):
    """The per-direction constants of ``_line_plan`` for direction index ``k`` (per lane)."""
    return {key: dr.gather(type(value), value, k) for key, value in tables.items()}


@dr.syntax
def _march_lines(texture, res, tables, direction_of_line, local_line, jb, jc, tau_lines):
    """Optical depth from the near face along every line of every direction in the batch.

    Lines run through the density extended sideways by its edge values (the texture's clamp
    mode); the gather only ever takes differences of tau over a voxel's in-box stretch. The
    trapezoid rule samples the near face, every slice crossing and the far face (finer sampling
    along the lines was measured not to help: the error is in the interpolation between lines).
    Writes ``tau_lines[buffer_offset + sample * lines + line]`` (sample-major, so neighbouring
    lanes store to neighbouring addresses).
    """
    d = _direction(tables, direction_of_line)
    near_face = d["origin"] + d["e_b"] * jb + d["e_c"] * jc + 0.5 * d["step"]
    target = d["buffer_offset"] + local_line
    tau = mi.Float(0.0)
    dr.scatter(tau_lines, tau, target)
    sigma_prev = texture.eval(near_face / res)[0]
    last = d["samples"] - 1
    u = mi.UInt32(1)
    while u <= last:
        # Sample u is slice u - 1; the last one is the far face, half a slice beyond the last slice.
        position = dr.select(u < last, mi.Float(u) - 0.5, d["slices"])
        sigma = texture.eval((near_face - d["step"] * position) / res)[0]
        length = dr.select((u == 1) | (u == last), 0.5, 1.0) * d["segment"]
        tau += 0.5 * (sigma_prev + sigma) * length
        dr.scatter(tau_lines, tau, target + u * d["lines"])
        sigma_prev = sigma
        u += 1


def _catmull_rom_weights(t):
    """Weights of the four taps at -1, 0, 1, 2 for Catmull-Rom interpolation at t in [0, 1)."""
    t2, t3 = t * t, t * t * t
    return (
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    )


def _slices_to_side(position, speed, size):
    """Slices travelled before leaving ``[0, size]`` on a lateral axis, moving ``speed`` per slice."""
    return dr.select(speed > 0, (size - position) / speed, dr.select(speed < 0, -position / speed, dr.inf))


@dr.syntax
def _gather_visibility(visibility, tau_lines, q, res, tables, count):
    """Add exp(-tau) for each direction and its antipode at every voxel centre.

    A voxel at slice ``m`` lies on a line of its own, inside a cell of the lattice. Toward the near
    face its line leaves the box at slice position ``mu+`` (the near face, or a side face for
    grazing directions), toward the far face at ``mu-``; the two optical depths are
    ``tau(m) - tau(mu+)`` and ``tau(mu-) - tau(m)``. ``tau(m)`` and ``tau(far face)`` are read from the
    4x4 surrounding lines by Catmull-Rom interpolation (bilinear leaves ~4x the error); the short
    stretches between an exit and its face, ``tau(mu+)`` and ``tau(far face) - tau(mu-)``, bilinearly.
    The lines see the density extended sideways, so tau is smooth across the side faces and
    interpolation stays accurate next to them, where the in-box optical depth of grazing
    directions changes by a whole chord within one voxel.
    """
    k = mi.UInt32(0)
    while k < count:
        d = _direction(tables, k)
        m = d["first"] + d["stride"] * (dr.dot(q, d["e_a"]) - 0.5)
        q_b, q_c = dr.dot(q, d["e_b"]), dr.dot(q, d["e_c"])
        step_b, step_c = dr.dot(d["step"], d["e_b"]), dr.dot(d["step"], d["e_c"])
        size_b, size_c = dr.dot(res, d["e_b"]), dr.dot(res, d["e_c"])
        xi_b = q_b - dr.dot(d["origin"], d["e_b"]) + m * step_b
        xi_c = q_c - dr.dot(d["origin"], d["e_c"]) + m * step_c
        jb, jc = dr.floor(xi_b), dr.floor(xi_c)
        fb, fc = xi_b - jb, xi_c - jc
        wb, wc = _catmull_rom_weights(fb), _catmull_rom_weights(fc)
        tap00 = d["buffer_offset"] + (mi.UInt32(jb) - 1) * d["lines_c"] + (mi.UInt32(jc) - 1)

        def tau_cubic(sample):
            """Catmull-Rom over the 4x4 lines around the voxel's line, and bilinear over the inner 2x2."""
            row = tap00 + sample * d["lines"]
            cubic, inner = mi.Float(0.0), []
            for db in range(4):
                for dc in range(4):
                    value = dr.gather(mi.Float, tau_lines, row + db * d["lines_c"] + dc)
                    cubic += wb[db] * wc[dc] * value
                    if db in (1, 2) and dc in (1, 2):
                        inner.append(value)
            return cubic, dr.lerp(dr.lerp(inner[0], inner[1], fc), dr.lerp(inner[2], inner[3], fc), fb)

        tau_here, _ = tau_cubic(mi.UInt32(dr.round(m)) + 1)
        tau_far, tau_far_bilinear = tau_cubic(d["samples"] - 1)

        def tau_at(mu):
            """tau at slice position mu in [-1/2, slices - 1/2] on the voxel's line, bilinear."""
            inner = dr.clip(mu, 0.0, d["slices"] - 1.0)
            sample = dr.select(mu < 0.0, 0.0, dr.select(mu > d["slices"] - 1.0, d["slices"], dr.floor(inner) + 1.0))
            fraction = dr.select(
                mu < 0.0,
                2.0 * (mu + 0.5),
                dr.select(mu > d["slices"] - 1.0, 2.0 * (mu - d["slices"] + 1.0), inner - dr.floor(inner)),
            )
            below = tap00 + mi.UInt32(sample) * d["lines"]
            values = []
            for offset in (below, below + d["lines"]):
                corner = [
                    dr.gather(mi.Float, tau_lines, offset + db * d["lines_c"] + dc) for db in (1, 2) for dc in (1, 2)
                ]
                values.append(dr.lerp(dr.lerp(corner[0], corner[1], fc), dr.lerp(corner[2], corner[3], fc), fb))
            return dr.lerp(values[0], values[1], fraction)

        to_near = dr.minimum(
            m + 0.5, dr.minimum(_slices_to_side(q_b, step_b, size_b), _slices_to_side(q_c, step_c, size_c))
        )
        to_far = dr.minimum(
            d["slices"] - 0.5 - m,
            dr.minimum(_slices_to_side(q_b, -step_b, size_b), _slices_to_side(q_c, -step_c, size_c)),
        )
        # Large optical depths come from the cubic reads; the bilinear ones only cover the stretch
        # between the exit and a face, outside the box sideways, where smoke is thin.
        tau_toward_near = tau_here - tau_at(m - to_near)
        tau_toward_far = (tau_far - tau_here) - (tau_far_bilinear - tau_at(m + to_far))
        visibility += dr.exp(-dr.maximum(tau_toward_near, 0.0)) + dr.exp(-dr.maximum(tau_toward_far, 0.0))
        k += 1
    return visibility
