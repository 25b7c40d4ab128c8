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
def state_status(x1: vec3, v1: vec3, use_domain: ti.template(), domain_lo: vec3, domain_hi: vec3) -> ti.i32:
    """ACTIVE, NON_FINITE (x1 or v1 is NaN/inf) or LEFT_DOMAIN for a resolved state."""
    status = P.ACTIVE
    if not (is_finite(x1) and is_finite(v1)):
        status = P.NON_FINITE
    elif ti.static(use_domain):
        if any(x1 < domain_lo) or any(x1 > domain_hi):
            status = P.LEFT_DOMAIN
    return status


@ti.func
def flag(p: ti.template(), i, status: ti.i32):
    """Freeze particle i with `status` and count it."""
    p.flags[i] = status
    if status == P.NON_FINITE:
        ti.atomic_add(p.stats[P.STAT_NON_FINITE], 1)
    else:
        ti.atomic_add(p.stats[P.STAT_LEFT_DOMAIN], 1)


@ti.func
def store(p: ti.template(), i, x0: vec3, v0: vec3, x1: vec3, v1: vec3,
          use_domain: ti.template(), domain_lo: vec3, domain_hi: vec3):
    """Write the resolved state back, freezing particles that went non-finite (at their last
    finite state) or left the domain (where they left)."""
    status = state_status(x1, v1, use_domain, domain_lo, domain_hi)
    if status != P.NON_FINITE:
        p.x[i] = x1
        p.v[i] = v1
    if status != P.ACTIVE:
        flag(p, i, status)
