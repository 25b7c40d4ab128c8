"""Time integration without collisions, and the end-of-substep bookkeeping (docs/physics.md 3).
Particle arguments `p` are the store's pack (types.ParticleArgs)."""

import taichi as ti

from ..types import ACTIVE, LEFT_DOMAIN, NON_FINITE, STAT_LEFT_DOMAIN, STAT_NON_FINITE, vec3


@ti.func
def symplectic_euler(x: vec3, v: vec3, acceleration: vec3, dt):
    """Candidate state (docs/physics.md 3): v' = v + dt a, x' = x + dt v'."""
    v1 = v + dt * acceleration
    return x + dt * v1, v1


@ti.func
def flight_path_bound(v0: vec3, gravity: vec3, dt, k):
    """Upper bound on the path length of k substeps of free flight from velocity v0: the
    substep displacements are dt v_j with v_j = v0 + j dt g (j = 1..k), and
    |v_j| <= |v0| + j dt |g| sums to k dt |v0| + dt^2 |g| k (k + 1) / 2."""
    return k * dt * v0.norm() + 0.5 * dt * dt * gravity.norm() * k * (k + 1)


@ti.func
def free_flight(x0: vec3, v0: vec3, gravity: vec3, dt, k):
    """k substeps of symplectic Euler without contacts in closed form:
    v_k = v0 + k dt g, x_k = x0 + k dt v0 + dt^2 g k (k + 1) / 2."""
    return x0 + (k * dt) * v0 + (0.5 * dt * dt * k * (k + 1)) * gravity, v0 + (k * dt) * gravity


@ti.func
def flight_stays_inside(x0: vec3, v0: vec3, gravity: vec3, dt, k, domain_lo: vec3, domain_hi: vec3) -> bool:
    """Every substep end of a k-substep free flight lies in the domain box. Per axis the
    positions x_j = x0 + j dt v0 + dt^2 g j (j + 1) / 2 are a parabola in j: its extremes over
    j = 1..k are at the ends or at the integer next to the vertex."""
    inside = True
    vertex = -v0 / (gravity * dt) - 0.5  # inf/nan on axes without gravity: clamped below
    for a in ti.static(range(3)):
        for choice in ti.static(range(4)):
            j = 1.0
            if ti.static(choice == 1):
                j = ti.cast(k, float)
            elif ti.static(choice == 2):
                j = ti.floor(vertex[a])
            elif ti.static(choice == 3):
                j = ti.floor(vertex[a]) + 1.0
            if not (j >= 1.0):  # also catches nan
                j = 1.0
            j = ti.min(j, ti.cast(k, float))
            xa = x0[a] + j * dt * v0[a] + 0.5 * dt * dt * j * (j + 1.0) * gravity[a]
            if not (xa >= domain_lo[a] and xa <= domain_hi[a]):
                inside = False
    return inside


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
    status = ACTIVE
    if not (is_finite(x1) and is_finite(v1)):
        status = NON_FINITE
    elif ti.static(use_domain):
        if any(x1 < domain_lo) or any(x1 > domain_hi):
            status = LEFT_DOMAIN
    return status


@ti.func
def flag(p: ti.template(), i, status: ti.i32):
    """Freeze particle i with `status` and count it."""
    p.flags[i] = status
    if status == NON_FINITE:
        ti.atomic_add(p.stats[STAT_NON_FINITE], 1)
    else:
        ti.atomic_add(p.stats[STAT_LEFT_DOMAIN], 1)


@ti.func
def store(p: ti.template(), i, x0: vec3, v0: vec3, x1: vec3, v1: vec3,
          use_domain: ti.template(), domain_lo: vec3, domain_hi: vec3):
    """Write the resolved state back, freezing particles that went non-finite (at their last
    finite state) or left the domain (where they left)."""
    status = state_status(x1, v1, use_domain, domain_lo, domain_hi)
    if status != NON_FINITE:
        p.x[i] = x1
        p.v[i] = v1
    if status != ACTIVE:
        flag(p, i, status)
