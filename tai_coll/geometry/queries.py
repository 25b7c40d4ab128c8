"""Host-side geometry queries: numpy in, numpy out, through the kernels' own @ti.func.

The kernels take ndarrays, so they compile once per dtype and serve every collider.
"""

import numpy as np
import taichi as ti

from .. import runtime
from ..scene.arrays import ShapeData
from . import kinds
from .crossing import world_crossing
from .sdf import vec3, vec4, world_sdf

mat3 = ti.math.mat3
# One collider's (1, 8) shape rows, read as 8-vectors like the collider table's columns
# (g.ishape[ci][k] in every geometry function).
SHAPE_INTS = ti.types.ndarray(dtype=ti.types.vector(8, ti.i32), ndim=1)
SHAPE_FLOATS = ti.types.ndarray(dtype=ti.types.vector(8, float), ndim=1)


@ti.kernel
def _sdf_kernel(groups: ti.template(), kind: ti.i32, params: vec4, center: vec3, rotation: mat3,
                ishape: SHAPE_INTS, fshape: SHAPE_FLOATS, fpool: ti.types.ndarray(),
                ipool: ti.types.ndarray(), points: ti.types.ndarray(),
                # outputs
                phi: ti.types.ndarray(), normal: ti.types.ndarray()):
    for i in range(points.shape[0]):
        x = vec3(points[i, 0], points[i, 1], points[i, 2])
        d, n = world_sdf(ShapeData(ishape, fshape, fpool, ipool, groups), 0, kind, params, center, rotation, x)
        phi[i] = d
        for k in ti.static(range(3)):
            normal[i, k] = n[k]


@ti.kernel
def _crossing_kernel(groups: ti.template(), kind: ti.i32, params: vec4, center: vec3, rotation: mat3,
                     ishape: SHAPE_INTS, fshape: SHAPE_FLOATS, fpool: ti.types.ndarray(),
                     ipool: ti.types.ndarray(), starts: ti.types.ndarray(), ends: ti.types.ndarray(), radius: float,
                     # outputs
                     hit: ti.types.ndarray(), fraction: ti.types.ndarray(),
                     normal: ti.types.ndarray()):
    for i in range(starts.shape[0]):
        x0 = vec3(starts[i, 0], starts[i, 1], starts[i, 2])
        x1 = vec3(ends[i, 0], ends[i, 1], ends[i, 2])
        h, t, n = world_crossing(ShapeData(ishape, fshape, fpool, ipool, groups), 0, kind, params, center, rotation,
                                 x0, x1, radius)
        hit[i] = 1 if h else 0
        fraction[i] = t
        for k in ti.static(range(3)):
            normal[i, k] = n[k]


def _shape_arrays(shape):
    """The collider's own shape data as a one-collider block (offsets 0), in kernel dtypes."""
    ishape, fshape, fdata, idata = shape.shape_data()
    dtype = runtime.float_dtype()
    return (np.ascontiguousarray(np.reshape(ishape, (1, 8)), dtype=np.int32),
            np.ascontiguousarray(np.reshape(fshape, (1, 8)), dtype=dtype),
            np.ascontiguousarray(fdata if len(fdata) else np.zeros(1), dtype=dtype),
            np.ascontiguousarray(idata if len(idata) else np.zeros(1), dtype=np.int32))


def signed_distance_and_normal(shape, points):
    kind, params, center, rotation = shape.kind, shape.params, shape.center, shape.rotation
    dtype = runtime.float_dtype()
    pts = np.ascontiguousarray(points, dtype=dtype)
    phi = np.zeros(len(pts), dtype=dtype)
    normal = np.zeros((len(pts), 3), dtype=dtype)
    if len(pts):
        _sdf_kernel(kinds.groups_of([kind]), kind, vec4(*params), vec3(*center), mat3(rotation), *_shape_arrays(shape), pts, phi, normal)
    return phi, normal


def segment_crossing(shape, starts, ends, radius):
    kind, params, center, rotation = shape.kind, shape.params, shape.center, shape.rotation
    dtype = runtime.float_dtype()
    x0 = np.ascontiguousarray(starts, dtype=dtype)
    x1 = np.ascontiguousarray(ends, dtype=dtype)
    hit = np.zeros(len(x0), dtype=np.int32)
    fraction = np.ones(len(x0), dtype=dtype)
    normal = np.zeros((len(x0), 3), dtype=dtype)
    if len(x0):
        _crossing_kernel(kinds.groups_of([kind]), kind, vec4(*params), vec3(*center), mat3(rotation), *_shape_arrays(shape), x0, x1,
                         radius, hit, fraction, normal)
    return hit.astype(bool), fraction, normal
