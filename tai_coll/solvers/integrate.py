"""Time integration without collisions, free flight in closed form (docs/physics.md 3.7), and the
end-of-substep bookkeeping (docs/physics.md 3).
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


@ti.func
def try_free_flight(x0: vec3, v0: vec3, clearance, gravity: vec3, dt, k, use_domain: ti.template(), domain_lo: vec3,
                    domain_hi: vec3):
    """k substeps at once when the clearance covers their whole path (and, with a domain,
    every substep's end stays inside it). Returns (done, x_k, v_k, clearance left)."""
    done = False
    xk, vk = x0, v0
    left = clearance
    if clearance > 0.0:
        path = flight_path_bound(v0, gravity, dt, k) * (1.0 + 1e-5)
        if clearance > path:
            xk, vk = free_flight(x0, v0, gravity, dt, k)
            inside = True
            if ti.static(use_domain):
                inside = flight_stays_inside(x0, v0, gravity, dt, k, domain_lo, domain_hi)
            if inside and state_status(xk, vk, False, domain_lo, domain_hi) == ACTIVE:
                done = True
                left = clearance - path
    return done, xk, vk, left


@ti.func
def try_flight_in_front(x0: vec3, v0: vec3, apart: vec3, level, others, gravity: vec3, dt, k_max,
                        use_domain: ti.template(), domain_lo: vec3, domain_hi: vec3):
    """The most substeps, up to k_max, that free flight keeps in front of the nearest
    collider's separating plane (apart . x > level, detect's) and within the clearance from
    the others, done at once in closed form (docs/physics.md 3.7). Along the flight
    apart . x_j - level = C + B j + A j^2 (x_j of free_flight); with gravity not pointing away
    from the plane (A <= 0) that is concave in j, so it stays positive up to its first root and
    the check at the last substep taken covers every one before it. A particle rising off a
    floor thus flies to the substep before it comes back down. Returns (k, x_k, v_k, apart . x_k
    - level, the others' clearance left); k = 0: no flight (A > 0, or not one substep clear)."""
    k = 0
    xk, vk = x0, v0
    ahead = apart.dot(x0) - level
    left = others
    a = 0.5 * dt * dt * apart.dot(gravity)
    b = dt * apart.dot(v0) + a
    if a <= 0.0 and ahead > 0.0:
        last = ti.cast(k_max, float)  # the first root, in substeps (beyond k_max: k_max)
        if a < 0.0:
            last = (-b - ti.sqrt(b * b - 4.0 * a * ahead)) / (2.0 * a)
        elif b < 0.0:
            last = -ahead / b
        j = ti.min(ti.cast(ti.floor(ti.min(last, ti.cast(k_max, float))), ti.i32), k_max)
        if j >= 1:
            path = flight_path_bound(v0, gravity, dt, j) * (1.0 + 1e-5)
            x_j, v_j = free_flight(x0, v0, gravity, dt, j)
            in_front = apart.dot(x_j) - level
            inside = True
            if ti.static(use_domain):
                inside = flight_stays_inside(x0, v0, gravity, dt, j, domain_lo, domain_hi)
            if (in_front > 0.0 and others > path and inside
                    and state_status(x_j, v_j, False, domain_lo, domain_hi) == ACTIVE):
                k, xk, vk, ahead, left = j, x_j, v_j, in_front, others - path
    return k, xk, vk, ahead, left
