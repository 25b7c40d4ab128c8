"""Sampling a signed-distance grid in kernels: trilinear phi and its analytic gradient.

docs/physics.md 1, triangle mesh row, the fast path (also the numpy-function `tc.Implicit`).
A grid collider's shape data (types.ShapeArgs, collider index ci):
- ishape: [0] offset of its node values in `fpool` (written by the packer), [1] unused
  (int pool offset), [2:5] nodes (nx, ny, nz); values in C order of (nx, ny, nz); [5]
  FACE_FLOORS when the values are followed by the least value on each face of the box
  (x low, x high, y low, y high, z low, z high; MeshSDF), else 0;
- fshape: [0:3] local position of node (0, 0, 0), [3] voxel size h (m), [4] a shift
  subtracted from every value (half the shell thickness of `MeshSDF(thickness=...)`).

Inside the grid phi is the trilinear interpolant of the node values and n its normalised
gradient (exact derivative of the interpolant, continuous across faces of cells only in
value). Outside the grid's box, with p_c its closest point to p and phi_c >= 0 the value
there, sqrt(|p - p_c|^2 + phi_c^2) is a lower bound on the distance (for any point s of a
convex box |p - s|^2 >= |p - p_c|^2 + |p_c - s|^2); it is what phi is when it reaches the
caller's `reach` (the particle's radius, say; INFINITY: never). Below that, the distance is
carried out of the box (Hopf-Lax), so that a particle of any radius, however far past the
padding, meets the surface where it is: the surface lies in the box, so the segment from
p to its nearest surface point s enters the box at a point b of a face that p lies beyond,
and |p - s| = |p - b| + dist(b). phi is the least |p - b| + phi(b) over p_c and the nodes of
those faces that could do better (|p - b| < the best so far, or reach, less the face's
least value): the distance to the grid's accuracy (a fraction of a cell, as inside), never
below the bound. A value phi_c < 0 at the box (a shell the box clips) gives
phi_c + |p - p_c|, 1-Lipschitz still.
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
INFINITY = 1e30
FACE_FLOORS = 1  # ishape[5]: the least value on each face of the box follows the node values


@ti.func
def _through_faces(g: ti.template(), ci, p: vec3, u: vec3, top: vec3, best, n: vec3):
    """The least of `best` (with normal n) and |p - b| + max(phi(b), 0) over the nodes b of
    the box's faces that p lies beyond (u: p in node units, top: the last node), each face
    searched within the disc where it could beat the best: |p - b| < best - the face's
    least value (0 when the grid does not store it). Returns (best, normal)."""
    meta = g.ishape[ci]
    f = g.fshape[ci]
    h = f[3]
    origin = vec3(f[0], f[1], f[2])
    stride = ti.Vector([meta[3] * meta[4], meta[4], 1], ti.i32)
    for axis in ti.static(range(3)):
        a1, a2 = ti.static((axis + 1) % 3, (axis + 2) % 3)
        for high in range(2):
            level = top[axis] * high  # the face's node index along `axis`
            beyond = (u[axis] - level) * h * (2 * high - 1)  # p's height over the face
            floor = 0.0
            if meta[5] == FACE_FLOORS:
                floor = ti.max(g.fpool[meta[0] + meta[2] * meta[3] * meta[4] + 2 * axis + high], 0.0)
            if beyond > 0.0 and best - floor > beyond:
                reach = ti.sqrt((best - floor) ** 2 - beyond * beyond) / h
                # The face's nodes within `reach` of p's foot (clamped in floats: no overflow).
                lo1 = ti.cast(ti.max(ti.ceil(u[a1] - reach), 0.0), ti.i32)
                hi1 = ti.cast(ti.min(ti.floor(u[a1] + reach), top[a1]), ti.i32)
                lo2 = ti.cast(ti.max(ti.ceil(u[a2] - reach), 0.0), ti.i32)
                hi2 = ti.cast(ti.min(ti.floor(u[a2] + reach), top[a2]), ti.i32)
                width = ti.max(hi2 - lo2 + 1, 0)
                for m in range(ti.max(hi1 - lo1 + 1, 0) * width):
                    node = ti.Vector([0, 0, 0], ti.i32)
                    node[axis] = ti.cast(level, ti.i32)
                    node[a1] = lo1 + m // width
                    node[a2] = lo2 + m % width
                    b = origin + h * node
                    dist = (p - b).norm()
                    value = ti.max(g.fpool[meta[0] + node.dot(stride)], 0.0)
                    if dist + value < best:
                        best, n = dist + value, (p - b) / dist
    return best, n


@ti.func
def grid_sdf(g: ti.template(), ci, p: vec3, reach=INFINITY):
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
            bound = ti.sqrt(d_out * d_out + phi * phi)
            value = bound
            n = (outside + phi * n).normalized()
            if bound < reach + f[4]:  # Hopf-Lax from the box (module docstring): p_c, then the faces' nodes
                value, n = _through_faces(g, ci, p, u, top, ti.min(d_out + phi, reach + f[4]), n)
                value = ti.max(value, bound)
        else:
            value = phi + d_out  # the surface leaves the box (a clipped shell): 1-Lipschitz still
            n = outside / d_out
        phi = value
    return phi - f[4], n


@ti.func
def _evaluate(g: ti.template(), ci, kind, params, p: vec3):
    """grid_sdf as marching.march_crossing calls an evaluator: params[0] is the reach
    (kind unused)."""
    return grid_sdf(g, ci, p, params[0])


@ti.func
def grid_crossing(g: ti.template(), ci, x0: vec3, x1: vec3, r):
    """Trajectory crossing against a grid: conservative advancement with the interpolant's
    Lipschitz bound, then bisection (geometry.marching). phi is needed exactly only within
    r of the surface; past r + L |x1 - x0| a bound lets the advance leave the segment in one
    step."""
    reach = r + LIPSCHITZ * (x1 - x0).norm()
    return march_crossing(_evaluate, g, ci, 0, ti.math.vec4(reach, 0.0, 0.0, 0.0), x0, x1, r, 1.0 / LIPSCHITZ,
                          False)
