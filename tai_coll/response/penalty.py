"""Penalty force laws of docs/physics.md 4 (seed 002), the one copy used by every kernel.

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

# A particle is a solid sphere: moment of inertia I = 2/5 m r^2 (with rotation).
SPHERE_INERTIA = 0.4

# Backward Euler or symplectic Euler for the normal spring-damper.
SYMPLECTIC_EULER = 0
BACKWARD_EULER = 1


@ti.func
def spring_damper(depth, vn, stiffness, damping):
    """docs/physics.md 4, seed 002: f_n = k_s depth - k_d (v_rel . n) along the outward normal,
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
    """Coulomb friction as a force, static and kinetic (docs/physics.md 4), regularised.

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
def rolling_torque(w_roll: vec3, fn, lever, inertia, dt, rolling_friction) -> vec3:
    """Rolling resistance as a torque (a particle that spins, PenaltySolver(rotation=True)):
    against w_roll, the relative angular velocity's part about axes in the tangent plane
    (rolling; spin about the normal is left alone), of at most rolling_friction * lever *
    |f_n| (lever: the rolling radius), and at most the torque I |w_roll| / dt that stops
    the rolling within the substep (the regularisation, as friction_force's cap)."""
    speed = w_roll.norm()
    return -ti.min(inertia / dt, rolling_friction * lever * fn / ti.max(speed, 1e-30)) * w_roll


@ti.func
def spin_friction(v1: vec3, w1: vec3, vs: vec3, ws: vec3, n: vec3, fn, mass, radius, dt, static_friction,
                  kinetic_friction, viscous_friction, rolling_friction):
    """Friction and rolling resistance of a spinning sphere (velocity v1, angular velocity
    w1, everything else this substep already applied) on a surface moving at vs and turning
    at ws at the contact point, outward normal n. The contact point -r n moves at
    v1 + w1 x (-r n) - vs; a tangential force f there also turns the sphere, dw = dt
    (-r n) x f / I. Returns (v1, w1).
    1. Stuck: the force that stops the slip (-m v_t / dt) and the torque that stops the
       rolling with it; kept when they are within mu_s |f_n| and mu_r r |f_n|: the sphere
       holds exactly (on an incline of tan(theta) <= mu_r, mu_s).
    2. Otherwise friction_force on the contact point's slip with the mass a tangential
       force there sees, m I / (I + m r^2) = 2/7 m: a sphere without slip then rolls
       (a = 5/7 g sin(theta) down an incline while mu_s >= 2/7 tan(theta)); then
       rolling_torque against the rolling that is left."""
    inertia = SPHERE_INERTIA * mass * radius * radius
    arm = -radius * n  # centre to contact point
    v_rel = v1 - vs
    w_rel = w1 - ws
    vt = v_rel - v_rel.dot(n) * n
    w_roll = w_rel - w_rel.dot(n) * n
    f_stick = -mass / dt * vt
    # the rolling resistance that holds the rolling still against f_stick's own torque
    torque_stick = -inertia / dt * w_roll - arm.cross(f_stick)
    if f_stick.norm() <= static_friction * fn and torque_stick.norm() <= rolling_friction * radius * fn:
        v1 += (dt / mass) * f_stick
        w1 -= w_roll  # dt (arm x f_stick + torque_stick) / I
    else:
        slip = vt + w_rel.cross(arm)
        f = friction_force(slip, fn, mass * inertia / (inertia + mass * radius * radius), dt, static_friction,
                           kinetic_friction, viscous_friction)
        v1 += (dt / mass) * f
        w1 += (dt / inertia) * arm.cross(f)
        w_rel = w1 - ws
        w1 += (dt / inertia) * rolling_torque(w_rel - w_rel.dot(n) * n, fn, radius, inertia, dt, rolling_friction)
    return v1, w1


@ti.func
def repulsion_profile(d, profile, strength, decay, reach):
    """f(d) of a repulsion field at gap d (m) between particle and surface (seed 002):
    exponential strength exp(-decay d), or linear max(0, strength - decay d); zero beyond
    `reach`. Inside (d < 0) both continue along their tangent at d = 0,
    strength (1 - decay d) and strength - decay d: growing with the depth (docs/physics.md 3's
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


@ti.func
def tangential_spring(spring: vec3, nrm: vec3, vt: vec3, fn, stiff, damp, ratio, dt, static_friction,
                      kinetic_friction, viscous_friction):
    """Coulomb friction with a tangential spring (Cundall and Strack; docs/physics.md 5): the
    static friction of docs/physics.md 4 held by the contact's own displacement. `spring` is
    the tangential displacement the contact has accumulated since it formed (zero for a new
    contact), projected onto the tangent plane of the current normal nrm and stretched by dt vt. (The contact plane
    turns by a small angle a per substep, and the projection shortens the spring by 1 -
    cos(a), second order in a; docs/design-notes.md has why it is not turned.) The
    force -k_t spring - D_t vt (k_t = ratio k_n, D_t = ratio D_n) holds while it is at most
    mu_s f_n; beyond, the contact slides: kinetic friction mu_k f_n (plus the wet term
    mu_v f_n |vt|) along the same direction, and the spring is cut back to the length that
    gives that force. Every step is odd in (nrm, vt, spring), so the two particles of a
    pair, which each keep the pair's spring, see exactly opposite springs and forces.
    Returns (force, spring)."""
    spring = spring - spring.dot(nrm) * nrm + dt * vt
    kt = ratio * stiff
    dt_damp = ratio * damp
    force = -kt * spring - dt_damp * vt
    limit = static_friction * fn
    if force.norm_sqr() > limit * limit:
        slide = (kinetic_friction + viscous_friction * vt.norm()) * fn
        force *= slide / force.norm()
        spring = -(force + dt_damp * vt) / ti.max(kt, 1e-30)
    return force, spring
