"""The collision routine of docs/physics.md 2, the one copy used by every kernel and by `collide()`.

Works on relative velocity only: callers subtract the object's (surface) velocity first
and add it back after, so the same law serves still and moving colliders alike.
"""

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
def pair_normal(xi: vec3, xj: vec3, i, j):
    """Unit normal from j to i; coincident centres get a fixed axis whose sign depends on
    the index order, so the two sides still see opposite normals. Branch-free (the passes
    call it for every listed neighbour)."""
    d = xi - xj
    dist = d.norm()
    axis = vec3(0.0, ti.select(i < j, -1.0, 1.0), 0.0)
    n = ti.select(dist > TINY, d / ti.max(dist, TINY), axis)
    return n, dist
