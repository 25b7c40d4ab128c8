"""Host-side geometry queries: numpy in, numpy out, through the kernels' own @ti.func
(geometry/dispatch.py), for a collider's `signed_distance`, `normal` and `crossing`.

The kernels take arrays, so they compile once per dtype and collider kind group and serve
every collider.
"""

import weakref

import numpy as np
import taichi as ti

from .. import runtime
from ..types import ShapeArgs, mat3, vec3, vec4
from . import kinds
from .dispatch import world_crossing, world_sdf


@ti.kernel
def _sdf_kernel(shape: ShapeArgs, groups: ti.template(), kind: ti.i32, params: vec4, center: vec3, rotation: mat3,
                points: ti.types.ndarray(),
                # outputs
                phi: ti.types.ndarray(), normal: ti.types.ndarray()):
    for i in range(points.shape[0]):
        x = vec3(points[i, 0], points[i, 1], points[i, 2])
        d, n = world_sdf(shape, groups, 0, kind, params, center, rotation, x)
        phi[i] = d
        for k in ti.static(range(3)):
            normal[i, k] = n[k]


@ti.kernel
def _crossing_kernel(shape: ShapeArgs, groups: ti.template(), kind: ti.i32, params: vec4, center: vec3,
                     rotation: mat3, starts: ti.types.ndarray(), ends: ti.types.ndarray(), radius: float,
                     # outputs
                     hit: ti.types.ndarray(), fraction: ti.types.ndarray(), normal: ti.types.ndarray()):
    for i in range(starts.shape[0]):
        x0 = vec3(starts[i, 0], starts[i, 1], starts[i, 2])
        x1 = vec3(ends[i, 0], ends[i, 1], ends[i, 2])
        h, t, n = world_crossing(shape, groups, 0, kind, params, center, rotation, x0, x1, radius)
        hit[i] = 1 if h else 0
        fraction[i] = t
        for k in ti.static(range(3)):
            normal[i, k] = n[k]


#: Each queried collider's ShapeArgs, by id: (the running Taichi's generation, the pack). An
#: entry leaves when its collider is collected (weakref.finalize).
_PACKS = {}


def _shape_args(shape) -> ShapeArgs:
    """The collider's own shape data as a one-collider block (offsets 0) in Taichi arrays of
    the kernel dtypes, made once per collider and Taichi runtime: a collider's shape data is
    fixed when it is made, and a pack of NumPy arrays cost about 1.2 ms a query in Python
    (building the pack, and Taichi's own launch path, which such a pack takes) against
    0.1 ms for the kernel of an emitter's 160 candidate points."""
    generation = runtime.ensure_init().generation
    kept = _PACKS.get(id(shape))
    if kept is not None and kept[0] == generation:
        return kept[1]
    ishape, fshape, fdata, idata = shape.shape_data()
    dtype = runtime.float_dtype()
    arrays = {}
    for name, values, kind, width in (("ishape", np.reshape(ishape, (1, 8)), np.int32, 8),
                                      ("fshape", np.reshape(fshape, (1, 8)), dtype, 8),
                                      ("fpool", fdata if len(fdata) else np.zeros(1), dtype, 0),
                                      ("ipool", idata if len(idata) else np.zeros(1), np.int32, 0)):
        taichi_type = ti.i32 if kind is np.int32 else float
        array = (ti.Vector.ndarray(width, taichi_type, shape=len(values)) if width else
                 ti.ndarray(taichi_type, shape=len(values)))
        array.from_numpy(np.ascontiguousarray(values, dtype=kind))
        arrays[name] = array
    pack = ShapeArgs(**arrays)
    if kept is None:
        weakref.finalize(shape, _PACKS.pop, id(shape), None)
    _PACKS[id(shape)] = (generation, pack)
    return pack


def _pose(shape):
    """The kernels' kind-dispatch arguments for a collider at its rest pose."""
    return dict(groups=kinds.groups_of([shape.kind]), kind=shape.kind, params=vec4(*shape.params),
                center=vec3(*shape.center), rotation=mat3(shape.rotation))


def signed_distance_and_normal(shape, points):
    dtype = runtime.float_dtype()
    pts = np.ascontiguousarray(points, dtype=dtype)
    phi = np.zeros(len(pts), dtype=dtype)
    normal = np.zeros((len(pts), 3), dtype=dtype)
    if len(pts):
        _sdf_kernel(shape=_shape_args(shape), **_pose(shape), points=pts, phi=phi, normal=normal)
    return phi, normal


def segment_crossing(shape, starts, ends, radius):
    dtype = runtime.float_dtype()
    x0 = np.ascontiguousarray(starts, dtype=dtype)
    x1 = np.ascontiguousarray(ends, dtype=dtype)
    hit = np.zeros(len(x0), dtype=np.int32)
    fraction = np.ones(len(x0), dtype=dtype)
    normal = np.zeros((len(x0), 3), dtype=dtype)
    if len(x0):
        _crossing_kernel(shape=_shape_args(shape), **_pose(shape), starts=x0, ends=x1, radius=radius, hit=hit,
                         fraction=fraction, normal=normal)
    return hit.astype(bool), fraction, normal
