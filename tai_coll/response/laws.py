"""The collision routine of docs/physics.md 2, the one copy used by every kernel and by `collide()`.

Works on relative velocity only: callers subtract the object's (surface) velocity first
and add it back after, so the same law serves still and moving colliders alike.
"""

import math

import taichi as ti

vec3 = ti.math.vec3

TINY = 1e-12  # below this tangential speed (m/s) the friction scale is moot: v_T is ~0

WET_LINEAR = 0       # v_T *= max(0, 1 - D dv_N)   (seed 001)
WET_EXPONENTIAL = 1  # v_T *= exp(-D dv_N)          (seed 001's unconditionally stable form)
WET_LAWS = {"linear": WET_LINEAR, "exponential": WET_EXPONENTIAL}


@ti.func
def respond(v_rel: vec3, n: vec3, restitution, friction, wet_friction, wet_law: ti.template()):
    """New relative velocity after a collision with outward unit normal n.

    docs/physics.md 2: only an approaching contact (v_N < 0) changes; v_N_new = -e v_N, so
    dv_N = (1 + e)|v_N|; dry Coulomb friction v_T *= max(0, 1 - mu dv_N / |v_T|) (static
    when the bracket reaches 0); then wet friction from D = wet_friction.
    Returns (v_rel_new, dv_N).
    """
    # Written without branches (selects instead): callers run it over many contacts in a
    # loop, and whether one approaches is not predictable; the selects give the same result.
    vn = v_rel.dot(n)
    approaching = vn < 0.0
    vt = v_rel - vn * n
    dvn = ti.select(approaching, (1.0 + restitution) * (-vn), 0.0)
    vt_len = vt.norm()
    # vt_len = 0: vt is zero too and the scale does not matter
    scale = ti.max(0.0, 1.0 - friction * dvn / ti.max(vt_len, TINY))
    if ti.static(wet_law == WET_LINEAR):
        scale *= ti.max(0.0, 1.0 - wet_friction * dvn)
    else:
        scale *= ti.exp(-wet_friction * dvn)
    out = ti.select(approaching, scale * vt - restitution * vn * n, v_rel)
    return out, dvn


@ti.func
def respond_pair(va: vec3, vb: vec3, inv_ma, inv_mb, n: vec3, restitution, friction,
                 wet_friction, wet_law: ti.template()):
    """Two movable bodies (docs/physics.md 2): n points from b to a.

    The law gives the wanted change of relative velocity; the impulse I solves
    dv_rel = (1/m_a + 1/m_b) I and is applied as +I/m_a, -I/m_b, so momentum is conserved.
    Returns (va_new, vb_new).
    """
    v_rel = va - vb
    v_new, dvn = respond(v_rel, n, restitution, friction, wet_friction, wet_law)
    impulse = (v_new - v_rel) / (inv_ma + inv_mb)
    return va + inv_ma * impulse, vb - inv_mb * impulse


@ti.func
def _mix(h):
    """An integer hash of a u32 (multiply-xorshift rounds)."""
    h ^= h >> 16
    h *= ti.u32(0x7FEB352D)
    h ^= h >> 15
    h *= ti.u32(0x846CA68B)
    h ^= h >> 16
    return h


@ti.func
def coincident_axis(i, j) -> vec3:
    """The normal from j to i of two particles whose centres coincide: a direction hashed from
    the two indices, uniform on the sphere, opposite on the two sides. One fixed axis for every
    such pair would push particles spawned on one point apart along a line (a column of them
    standing on a floor) instead of into a ball (docs/physics.md 5.2.1)."""
    h = _mix(ti.cast(ti.min(i, j), ti.u32) * ti.u32(0x9E3779B1) + _mix(ti.cast(ti.max(i, j), ti.u32)))
    z = ti.cast(h >> 8, float) * (2.0 / 16777216.0) - 1.0  # uniform on the sphere: z and an angle
    phi = ti.cast(_mix(h) >> 8, float) * (2.0 * math.pi / 16777216.0)
    across = ti.sqrt(ti.max(1.0 - z * z, 0.0))
    return ti.select(i < j, -1.0, 1.0) * vec3(across * ti.cos(phi), across * ti.sin(phi), z)


@ti.func
def pair_normal(xi: vec3, xj: vec3, i, j):
    """Unit normal from j to i and the distance; coincident centres (within TINY) get
    coincident_axis(i, j), so the two sides still see opposite normals. The hash sits behind
    a branch that particles apart never take (the passes call this for every listed
    neighbour)."""
    d = xi - xj
    dist = d.norm()
    axis = vec3(0.0, 0.0, 0.0)
    if dist <= TINY:
        axis = coincident_axis(i, j)
    return ti.select(dist > TINY, d / ti.max(dist, TINY), axis), dist
