"""Sampling a signed-distance grid in kernels: trilinear phi and its analytic gradient.

docs/physics.md 1, triangle mesh row, the fast path (also the numpy-function `tc.Implicit`).
A grid collider's shape data (types.ShapeArgs, collider index ci):
- ishape: [0] offset of its node values in `fpool` (written by the packer), [1] unused
  (int pool offset), [2:5] nodes (nx, ny, nz); values in C order of (nx, ny, nz);
- fshape: [0:3] local position of node (0, 0, 0), [3] voxel size h (m), [4] a shift
  subtracted from every value (half the shell thickness of `MeshSDF(thickness=...)`).

Inside the grid phi is the trilinear interpolant of the node values and n its normalised
gradient (exact derivative of the interpolant, continuous across faces of cells only in
value). Outside the grid's box, with p_c the closest point of the box and phi_c >= 0 the
value there: phi = sqrt(|p - p_c|^2 + phi_c^2). The surface lies inside the box, and for
any point s of a convex box |p - s|^2 >= |p - p_c|^2 + |p_c - s|^2, so this never exceeds
the true distance (it stays safe for conservative advancement) and is continuous at the box.
"""

import math

import numpy as np
import taichi as ti

from .marching import march_crossing

vec3 = ti.math.vec3

# The most nodes a grid may have (MeshSDF's bake, a numpy function's tc.Implicit): 128 MiB
# of values in f64, and a cap on what a typo in resolution or voxel_size asks for.
MAX_NODES = 256 ** 3


def node_counts(span, h: float, *, name: str) -> np.ndarray:
    """Nodes per axis (int64, at least 2) of a grid of spacing h over a box of `span` (m),
    or ValueError naming `name` beyond MAX_NODES. Counted in floats first: a tiny h would
    overflow an integer count and wrap around to a small grid."""
    nodes = np.maximum(np.ceil(np.asarray(span, dtype=np.float64) / h - 1e-9) + 1, 2)
    if np.prod(nodes) > MAX_NODES:
        raise ValueError(f"{name}: the grid would have {np.prod(nodes):.4g} nodes "
                         f"({' x '.join(f'{n:.6g}' for n in nodes)}), more than {MAX_NODES:,}; "
                         "use a lower resolution or a larger voxel_size")
    return nodes.astype(np.int64)


# The trilinear interpolant of a 1-Lipschitz node function is sqrt(3)-Lipschitz at most
# (each derivative is a convex combination of node differences, each <= 1 per cell).
LIPSCHITZ = math.sqrt(3.0)
TINY = 1e-12


@ti.func
def grid_sdf(g: ti.template(), ci, p: vec3):
    meta = g.ishape[ci]
    f = g.fshape[ci]
    base = meta[0]
    nx = meta[2]
    ny = meta[3]
    nz = meta[4]
    origin = vec3(f[0], f[1], f[2])
    h = f[3]
    u = (p - origin) / h
    top = vec3(nx - 1, ny - 1, nz - 1)
    uc = ti.math.clamp(u, 0.0, top)
    cell = ti.cast(ti.min(ti.floor(uc), top - 1.0), ti.i32)
    w = uc - cell
    i0 = base + (cell[0] * ny + cell[1]) * nz + cell[2]
    sy = nz
    sx = ny * nz
    c000 = g.fpool[i0]
    c001 = g.fpool[i0 + 1]
    c010 = g.fpool[i0 + sy]
    c011 = g.fpool[i0 + sy + 1]
    c100 = g.fpool[i0 + sx]
    c101 = g.fpool[i0 + sx + 1]
    c110 = g.fpool[i0 + sx + sy]
    c111 = g.fpool[i0 + sx + sy + 1]
    # Interpolate along z, then y, then x; the gradient differentiates each stage.
    c00 = c000 + w[2] * (c001 - c000)
    c01 = c010 + w[2] * (c011 - c010)
    c10 = c100 + w[2] * (c101 - c100)
    c11 = c110 + w[2] * (c111 - c110)
    c0 = c00 + w[1] * (c01 - c00)
    c1 = c10 + w[1] * (c11 - c10)
    phi = c0 + w[0] * (c1 - c0)
    dz0 = (c001 - c000) + w[1] * ((c011 - c010) - (c001 - c000))
    dz1 = (c101 - c100) + w[1] * ((c111 - c110) - (c101 - c100))
    grad = vec3(c1 - c0, (c01 - c00) + w[0] * ((c11 - c10) - (c01 - c00)), dz0 + w[0] * (dz1 - dz0)) / h
    gnorm = grad.norm()
    n = vec3(0.0, 1.0, 0.0)
    if gnorm > TINY:
        n = grad / gnorm
    outside = (u - uc) * h
    d_out = outside.norm()
    if d_out > 0.0:
        value = 0.0
        if phi >= 0.0:
            value = ti.sqrt(d_out * d_out + phi * phi)
            n = (outside + phi * n).normalized()
        else:
            value = phi + d_out  # the surface leaves the box (a clipped shell): 1-Lipschitz still
            n = outside / d_out
        phi = value
    return phi - f[4], n


@ti.func
def _evaluate(g: ti.template(), ci, kind, params, p: vec3):
    """grid_sdf as marching.march_crossing calls an evaluator (kind and params unused)."""
    return grid_sdf(g, ci, p)


@ti.func
def grid_crossing(g: ti.template(), ci, x0: vec3, x1: vec3, r):
    """Trajectory crossing against a grid: conservative advancement with the interpolant's
    Lipschitz bound, then bisection (geometry.marching)."""
    return march_crossing(_evaluate, g, ci, 0, ti.math.vec4(0.0), x0, x1, r, 1.0 / LIPSCHITZ, False)
