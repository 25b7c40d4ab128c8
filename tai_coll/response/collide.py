"""`collide()` and `collide_pair()`: the black-box routine of docs/physics.md 2 on numpy arrays."""


import numpy as np
import taichi as ti

from .. import runtime, validate
from .laws import WET_LAWS, respond, respond_pair, vec3


@ti.func
def _vec(a: ti.types.ndarray(), i):
    return vec3(a[i, 0], a[i, 1], a[i, 2])


@ti.kernel
def _collide_kernel(v: ti.types.ndarray(), n: ti.types.ndarray(), v_obj: ti.types.ndarray(),
                    restitution: float, friction: float, wet_friction: float, wet_law: ti.template(),
                    # outputs
                    out: ti.types.ndarray()):
    for i in range(v.shape[0]):
        vo = _vec(v_obj, i)
        v_rel, dvn = respond(_vec(v, i) - vo, _vec(n, i), restitution, friction, wet_friction, wet_law)
        for k in ti.static(range(3)):
            out[i, k] = vo[k] + v_rel[k]


@ti.kernel
def _pair_kernel(va: ti.types.ndarray(), vb: ti.types.ndarray(), n: ti.types.ndarray(),
                 inv_ma: ti.types.ndarray(), inv_mb: ti.types.ndarray(),
                 restitution: float, friction: float, wet_friction: float, wet_law: ti.template(),
                 # outputs
                 out_a: ti.types.ndarray(), out_b: ti.types.ndarray()):
    for i in range(va.shape[0]):
        a, b = respond_pair(_vec(va, i), _vec(vb, i), inv_ma[i], inv_mb[i], _vec(n, i),
                            restitution, friction, wet_friction, wet_law)
        for k in ti.static(range(3)):
            out_a[i, k] = a[k]
            out_b[i, k] = b[k]


def _rows(name, value, count):
    """Broadcast a (3,) or (count, 3) argument to (count, 3)."""
    arr = validate.points(name, value)
    if arr.shape[0] == 1 and count != 1:
        arr = np.repeat(arr, count, axis=0)
    if arr.shape[0] != count:
        raise ValueError(f"{name} must have shape (3,) or ({count}, 3); got {arr.shape}")
    return arr


def _unit_normals(n, count):
    n = _rows("n", n, count)
    lengths = np.linalg.norm(n, axis=1)
    if np.any(lengths < 1e-12):
        raise ValueError(f"n must be non-zero; row {int(np.argmin(lengths))} has zero length")
    return n / lengths[:, None]


def _law_args(restitution, friction, wet_friction, wet_law):
    restitution = validate.real("restitution", restitution, low=0.0, high=1.0)
    friction = validate.real("friction", friction, low=0.0)
    wet_friction = validate.real("wet_friction", wet_friction, low=0.0)
    if wet_law not in WET_LAWS:
        raise ValueError(f"wet_law must be one of {tuple(WET_LAWS)}; got {wet_law!r}")
    return restitution, friction, wet_friction, WET_LAWS[wet_law]


def collide(v, n, restitution=0.5, friction=0.0, object_velocity=None, *, wet_friction=0.0,
            wet_law="linear") -> np.ndarray:
    """New particle velocities after colliding with an object (docs/physics.md 2).

    v: (N, 3) or (3,) particle velocities (m/s). n: outward unit normals of the object,
    (N, 3) or one (3,) for all (normalised here). restitution e in [0, 1]; friction mu >= 0
    (dry Coulomb); wet_friction D >= 0 in s/m, applied as `wet_law` ("linear":
    max(0, 1 - D dv_N), or "exponential": exp(-D dv_N)). object_velocity: the surface
    velocity of the object at the contact (None: at rest). Separating contacts are returned
    unchanged. Returns an array shaped like v.
    """
    runtime.ensure_init()
    single = np.ndim(v) == 1
    v_arr = validate.points("v", v)
    count = len(v_arr)
    n_arr = _unit_normals(n, count)
    vo = np.zeros((count, 3)) if object_velocity is None else _rows("object_velocity", object_velocity, count)
    args = _law_args(restitution, friction, wet_friction, wet_law)
    dtype = runtime.float_dtype()
    out = np.zeros((count, 3), dtype=dtype)
    if count:
        cast = [np.ascontiguousarray(a, dtype=dtype) for a in (v_arr, n_arr, vo)]
        _collide_kernel(*cast, *args, out)
    return out[0] if single else out


def collide_pair(va, vb, n, mass_a, mass_b, restitution=0.5, friction=0.0, *, wet_friction=0.0,
                 wet_law="linear"):
    """Equal and opposite impulses between two movable bodies (docs/physics.md 2).

    n: unit normal pointing from body b to body a. mass_a, mass_b: kg (> 0; np.inf makes a
    body immovable). Returns (va_new, vb_new); the total momentum is unchanged.
    """
    runtime.ensure_init()
    single = np.ndim(va) == 1
    va_arr = validate.points("va", va)
    count = len(va_arr)
    vb_arr = _rows("vb", vb, count)
    n_arr = _unit_normals(n, count)
    inv = []
    for name, m in (("mass_a", mass_a), ("mass_b", mass_b)):
        m = np.broadcast_to(np.asarray(m, dtype=np.float64), (count,))
        if np.any(np.isnan(m)) or np.any(m <= 0):
            raise ValueError(f"{name} must be > 0 (np.inf for an immovable body)")
        validate.representable(name, m[np.isfinite(m)])  # (1e-50 kg would be an infinite 1/m in f32)
        inv.append(1.0 / m)
    if np.any((inv[0] == 0) & (inv[1] == 0)):
        raise ValueError("mass_a and mass_b cannot both be infinite")
    args = _law_args(restitution, friction, wet_friction, wet_law)
    dtype = runtime.float_dtype()
    out_a = np.zeros((count, 3), dtype=dtype)
    out_b = np.zeros((count, 3), dtype=dtype)
    if count:
        cast = [np.ascontiguousarray(a, dtype=dtype) for a in (va_arr, vb_arr, n_arr, inv[0], inv[1])]
        _pair_kernel(*cast, *args, out_a, out_b)
    return (out_a[0], out_b[0]) if single else (out_a, out_b)
