"""Penalty force laws of PHYSICS.md 4 (seed 002), the one copy used by every kernel.

Forces, not impulses: a zero-length viscoelastic spring at the point of entry pushes a
penetrating particle out, friction is a force bounded by mu |f_n|, and repulsion fields act
at a distance. Like `laws.respond`, these work on velocity relative to the collider's
surface: callers subtract the surface velocity first.
"""

import taichi as ti

vec3 = ti.math.vec3

# Repulsion field kinds and profiles, as stored per collider (solvers.penalty) and in the
# impulse solver's last-resort field.
FIELD_NONE = 0
FIELD_VELOCITY = 1  # v(x) = f(d) n: the relative normal velocity is raised to at least f(d)
FIELD_FORCE = 2     # f(x) = f(d) n: added to the particle's forces
PROFILE_EXPONENTIAL = 0  # f(d) = strength exp(-decay d)
PROFILE_LINEAR = 1       # f(d) = max(0, strength - decay d)

# Backward Euler or symplectic Euler for the normal spring-damper.
SYMPLECTIC_EULER = 0
BACKWARD_EULER = 1


@ti.func
def spring_damper(depth, vn, stiffness, damping):
    """PHYSICS.md 4, seed 002: f_n = k_s depth - k_d (v_rel . n) along the outward normal,
    for a penetration `depth` > 0 and relative normal velocity vn. Only pushing: f_n >= 0
    (a separating particle is not held back by the damper)."""
    return ti.max(0.0, stiffness * depth - damping * vn)


@ti.func
def spring_damper_implicit(depth, vn, an, mass, stiffness, damping, dt):
    """The same spring-damper integrated by backward Euler along n (1-D, per contact).

    With u the relative normal velocity at t + dt and the depth there depth - dt u,
        m (u - vn) = dt (m a_n + k (depth - dt u) - D u)
    is linear in u:
        u = (m vn + dt (m a_n + k depth)) / (m + dt D + dt^2 k),
    and the force that produces it is f_n = k (depth - dt u) - D u (a_n: the normal part of
    the other accelerations, gravity). Stable for any dt, but damped: the rebound of an
    undamped contact loses energy, more with larger dt (seed 002: implicit integration buys
    stability, not accuracy). Only pushing: f_n >= 0."""
    u = (mass * vn + dt * (mass * an + stiffness * depth)) / (mass + dt * damping + dt * dt * stiffness)
    return ti.max(0.0, stiffness * (depth - dt * u) - damping * u)


@ti.func
def friction_force(vt_pred: vec3, fn, mass, dt, static_friction, kinetic_friction, viscous_friction) -> vec3:
    """Coulomb friction as a force, static and kinetic (PHYSICS.md 4), regularised.

    vt_pred: the tangential relative velocity the particle would have at the end of the
    substep without friction (its velocity plus dt times every other force so far). The
    force that would stop it, f_stop = -m vt_pred / dt, is the traction: static friction
    supplies it while |f_stop| <= mu_s |f_n| (the particle holds, exactly). Beyond that the
    contact slides with the kinetic force mu_k |f_n| plus the viscous (wet) force
    mu_v |f_n| |v_t|, along -vt_pred, capped at |f_stop| so that friction never reverses
    the sliding direction within a substep. The cap is the regularisation at v_t -> 0: no
    chatter, no division by zero.
    """
    speed = vt_pred.norm()
    f_stop = -mass / dt * vt_pred
    need = mass / dt * speed  # |f_stop|
    force = f_stop
    if need > static_friction * fn:
        slide = ti.min(need, (kinetic_friction + viscous_friction * speed) * fn)
        force = (slide / need) * f_stop
    return force


@ti.func
def repulsion_profile(d, profile, strength, decay, reach):
    """f(d) of a repulsion field at gap d (m) between particle and surface (seed 002):
    exponential strength exp(-decay d), or linear max(0, strength - decay d); zero beyond
    `reach`. Inside (d < 0) both continue along their tangent at d = 0,
    strength (1 - decay d) and strength - decay d: growing with the depth (PHYSICS.md 3's
    last resort, a push proportional to penetration), and bounded."""
    f = 0.0
    if d < reach:
        if d < 0.0:
            if profile == PROFILE_EXPONENTIAL:
                f = strength * (1.0 - decay * d)
            else:
                f = strength - decay * d
        elif profile == PROFILE_EXPONENTIAL:
            f = strength * ti.exp(-decay * d)
        else:
            f = ti.max(0.0, strength - decay * d)
    return f


@ti.func
def apply_repulsion(v_rel: vec3, n: vec3, d, mass, dt, kind, profile, strength, decay, reach) -> vec3:
    """One substep of a repulsion field on relative velocity v_rel (seed 002).
    Velocity field: the normal component is raised to at least f(d) (a particle moving
    away faster keeps its speed). Force field: f(d) n acts for dt, dv = dt f(d) / m n."""
    f = repulsion_profile(d, profile, strength, decay, reach)
    out = v_rel
    if kind == FIELD_VELOCITY:
        vn = v_rel.dot(n)
        if vn < f:
            out = v_rel + (f - vn) * n
    elif kind == FIELD_FORCE:
        out = v_rel + (dt * f / mass) * n
    return out
