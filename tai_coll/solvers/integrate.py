"""Time integration without collisions, and the end-of-substep bookkeeping."""

import taichi as ti

from ..scene import particles as P

vec3 = ti.math.vec3


@ti.func
def symplectic_euler(x: vec3, v: vec3, acceleration: vec3, dt):
    """Candidate state (PHYSICS.md 3): v' = v + dt a, x' = x + dt v'."""
    v1 = v + dt * acceleration
    return x + dt * v1, v1


@ti.func
def is_finite(a: vec3) -> bool:
    finite = True
    for k in ti.static(range(3)):
        if ti.math.isnan(a[k]) or ti.math.isinf(a[k]):
            finite = False
    return finite


@ti.func
def store(p: ti.template(), i, x0: vec3, v0: vec3, x1: vec3, v1: vec3,
          use_domain: ti.template(), domain_lo: vec3, domain_hi: vec3):
    """Write the resolved state back, freezing particles that went non-finite or left the domain."""
    if not (is_finite(x1) and is_finite(v1)):
        p.flags[i] = P.NON_FINITE
        ti.atomic_add(p.stats[P.STAT_NON_FINITE], 1)
    else:
        p.x[i] = x1
        p.v[i] = v1
        if ti.static(use_domain):
            if any(x1 < domain_lo) or any(x1 > domain_hi):
                p.flags[i] = P.LEFT_DOMAIN
                ti.atomic_add(p.stats[P.STAT_LEFT_DOMAIN], 1)
