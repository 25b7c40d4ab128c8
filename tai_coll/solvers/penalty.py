"""Penalty-based contact resolution: docs/physics.md 4, seed 002. Forces instead of impulses.

One substep of one particle reads as: gather its state; sum the forces of every collider
within reach at the start of the substep (a zero-length spring-damper at the point of entry
while it penetrates, friction bounded by mu |f_n|, and the collider's repulsion field if it
has one); integrate with symplectic Euler, v1 = v0 + dt (g + F / m), x1 = x0 + dt v1; scatter.
Optionally the normal spring-damper is integrated by backward Euler (stable at any dt,
damped).

The contact forces are summed in a running velocity: v1 starts at v0 + dt g and each
contact adds dt f / m in turn, so the friction of a contact sees every force before it
(gravity and its own normal force on an incline, say) and can hold the particle exactly.
Like the impulse solver, particles are independent, one parallel loop runs over them, and
with colliders that hold still one launch runs several substeps and carries each particle's
clearance: while it is farther from every collider (and its field) than it moves, the
substep is free flight.

The substep kernel comes in variants (`penalty_kernel`): for particles that spin or not, and
with per-particle loads from particle pairs (DEM forces, torques) or not. Each takes only the
arrays it reads; Taichi kernels have fixed signatures, so a variant compiled without a
feature gets the Unused pack in that feature's place.
"""

import functools
import math
import weakref

import numpy as np
import taichi as ti

from .. import notices, params, runtime, validate
from ..geometry.colliders import Collider
from ..response.penalty import (BACKWARD_EULER, FIELD_NONE, SPHERE_INERTIA, SYMPLECTIC_EULER, apply_repulsion,
                                friction_force, spin_friction, spring_damper, spring_damper_implicit)
from ..response.exchange import record_force
from ..response.repulsion import pack
from ..types import ACTIVE, ARRAY, NON_FINITE, ColliderArgs, ParticleArgs, SpinArgs, Unused, host_vector, unused, vec3
from .base import Solver
from .detection import BOUND_SLOT, INFINITY, carried, collider_sdf, surface_velocity
from .integrate import store

#: Loads on particles from outside the solver (DEM pairs): forces (N), and for spinning
#: particles torques (N m), held for one substep.
Forces = ti.types.argpack(force=ARRAY)
ForcesAndTorques = ti.types.argpack(force=ARRAY, torque=ARRAY)

INTEGRATORS = {"symplectic_euler": SYMPLECTIC_EULER, "backward_euler": BACKWARD_EULER}

# Columns of the solver's per-collider table (one row per collider of the scene).
STATIC_FRICTION, KINETIC_FRICTION, VISCOUS_FRICTION = 0, 1, 2
FIELD_KIND, FIELD_PROFILE, FIELD_STRENGTH, FIELD_DECAY, FIELD_RANGE = 3, 4, 5, 6, 7
ROLLING_FRICTION = 8
TABLE_WIDTH = 9

#: The scene warns when dt exceeds this multiple of the recommended dt (always inside the
#: explicit stability limit, which lies at least 2.7 recommended dt away: see params).
WARN_FACTOR = 2.0


def impact_depth_factor(damping_ratio: float) -> float:
    """The deepest a spring-damper contact lets a particle sink when struck at speed V, in
    units of V / w (w = sqrt(k / m)): the maximum of x(t) for m x'' = -k x - D x', x(0) = 0,
    x'(0) = V. Undamped 1, critically damped 1/e, less the more damping."""
    zeta = damping_ratio
    root = math.sqrt(abs(1.0 - zeta * zeta))
    if root < 1e-6:
        return math.exp(-1.0)  # critically damped: x = V t exp(-w t), deepest at w t = 1
    if zeta < 1.0:
        return math.exp(-zeta / root * math.atan2(root, zeta))  # x = V / w_d exp(-zeta w t) sin(w_d t)
    s1, s2 = -zeta + root, -zeta - root  # overdamped: the two decay rates, in units of w
    peak = math.log(s2 / s1) / (s1 - s2)
    return (math.exp(s1 * peak) - math.exp(s2 * peak)) / (s1 - s2)


@ti.func
def contact_constants(m, stiffness, stiffness_per_mass, damping, damping_is_ratio):
    """Per particle k (N/m) and D (N s/m). stiffness_per_mass: `stiffness` holds (2 pi f)^2,
    k = m (2 pi f)^2; damping_is_ratio: `damping` holds zeta, D = 2 zeta sqrt(m k)."""
    k = stiffness
    d = damping
    if stiffness_per_mass != 0:
        k = m * stiffness
        if damping_is_ratio != 0:
            d = 2.0 * damping * m * ti.sqrt(stiffness)  # sqrt(m k) = m sqrt((2 pi f)^2): hoisted out of loops
    elif damping_is_ratio != 0:
        d = 2.0 * damping * ti.sqrt(m * k)
    return k, d


@ti.func
def contact_velocity(c: ti.template(), groups: ti.template(), table: ti.template(), i, x0: vec3, v0: vec3, v1: vec3,
                     w1: vec3, m, r, gravity: vec3, dt, k, d, integrator, spinning: ti.template()):
    """Every collider's forces on a particle at (x0, v0), colliders at their start pose.
    spinning: the particle spins (angular velocity w1): friction acts at the contact point
    and turns it, with rolling resistance (spin_friction). Returns (v1 and w1 with the
    forces applied, the clearance: a lower bound on the distance from the particle's
    surface to the nearest collider's reach)."""
    clearance = INFINITY
    for ci in range(c.count):
        row = table[ci]
        field_range = row[FIELD_RANGE]
        # Outside the bounding sphere and the field: no force (phi is 1-Lipschitz). A plane's
        # "sphere" is 1e30 m: a particle blown that far still meets it (and its run is
        # reported non-finite, instead of flying on for ever).
        bound = c.params[ci][BOUND_SLOT]
        reach = (x0 - c.center0[ci]).norm() - bound - r
        if reach > field_range and bound < Collider.UNBOUNDED:
            clearance = ti.min(clearance, reach - field_range)
            continue
        phi, n = collider_sdf(c, groups, ci, x0, False, r + field_range)
        gap = phi - r
        clearance = ti.min(clearance, gap - field_range)
        field_kind = ti.cast(row[FIELD_KIND], ti.i32)
        if gap < 0.0 or (field_kind != FIELD_NONE and gap < field_range):
            # query: the surface velocity at the closest surface point (relative velocity)
            vs = surface_velocity(c, ci, carried(c, ci, x0 - phi * n))
            v_before = v1
            if gap < 0.0:
                # respond: docs/physics.md 4, the spring-damper at the point of entry, depth = r - phi
                vn = (v0 - vs).dot(n)
                an = gravity.dot(n)
                mc = m  # the contact's mass: the particle's, or with a body the pair's reduced mass
                if c.body[ci] >= 0:
                    # docs/physics.md 7.3: a body falls too (its predicted velocity vs has this
                    # substep's gravity), and moves under the force as well
                    vn = (v0 + dt * gravity - vs).dot(n)
                    an = 0.0
                    arm = (x0 - c.body_com[ci]).cross(n)
                    mc = 1.0 / (1.0 / m + c.body_inv_mass[ci] + arm.dot(c.body_inv_inertia[ci] @ arm))
                fn = 0.0
                if integrator == BACKWARD_EULER:
                    fn = spring_damper_implicit(-gap, vn, an, mc, k, d, dt)
                elif c.body[ci] >= 0:
                    # the damper on the reduced mass, capped where its explicit step would turn
                    # the relative normal velocity round (a body lighter than the particle
                    # shortens the contact's characteristic time below the particle's own)
                    fn = spring_damper(-gap, vn, k, ti.min(d, mc / dt))
                else:
                    fn = spring_damper(-gap, vn, k, d)
                v1 += (dt * fn / m) * n
                # friction against the tangential velocity every force so far would leave
                if ti.static(spinning):
                    v1, w1 = spin_friction(v1, w1, vs, c.angular_velocity[ci], n, fn, m, r, dt, row[STATIC_FRICTION],
                                           row[KINETIC_FRICTION], row[VISCOUS_FRICTION], row[ROLLING_FRICTION])
                else:
                    v_rel = v1 - vs
                    vt = v_rel - v_rel.dot(n) * n
                    v1 += (dt / m) * friction_force(vt, fn, mc, dt, row[STATIC_FRICTION], row[KINETIC_FRICTION],
                                                    row[VISCOUS_FRICTION])
            if field_kind != FIELD_NONE:
                # seed 002: the collider's repulsion field
                v1 = vs + apply_repulsion(v1 - vs, n, gap, m, dt, field_kind, ti.cast(row[FIELD_PROFILE], ti.i32),
                                          row[FIELD_STRENGTH], row[FIELD_DECAY], field_range)
            if c.body[ci] >= 0:  # a rigid body takes the opposite (docs/physics.md 7.3)
                record_force(c, ci, i, x0, m * (v1 - v_before))
    return v1, w1, clearance


@ti.func
def penalty_particle(p: ti.template(), c: ti.template(), groups: ti.template(), table: ti.template(), i,
                     gravity: vec3, dt, stiffness, stiffness_per_mass, damping, damping_is_ratio, integrator,
                     use_domain: ti.template(), domain_lo: vec3, domain_hi: vec3, clearance, spin: ti.template(),
                     loads: ti.template(), spinning: ti.template(), loaded: ti.template()):
    """One substep of particle i; returns its clearance after the substep (<= 0: unknown).
    loaded: loads.force[i] (N, from other particles) joins gravity, and with spinning
    loads.torque[i] (N m) turns the particle. spinning: spin.w[i] holds the particle's
    angular velocity (rad/s), integrated like v: w1 = w0 + dt tau / I."""
    if p.flags[i] == ACTIVE:
        # gather
        x0 = p.x[i]
        v0 = p.v[i]
        m = p.mass[i]
        r = p.radius[i]
        # forces: gravity (and given loads), then the colliders within reach (none while the
        # clearance lasts)
        v1 = v0 + dt * gravity
        w1 = vec3(0.0, 0.0, 0.0)
        if ti.static(spinning):
            w1 = spin.w[i]
        if ti.static(loaded):
            v1 += (dt / m) * loads.force[i]
            if ti.static(spinning):
                w1 += (dt / (SPHERE_INERTIA * m * r * r)) * loads.torque[i]
        if clearance <= 0.0:
            k, d = contact_constants(m, stiffness, stiffness_per_mass, damping, damping_is_ratio)
            v1, w1, clearance = contact_velocity(c, groups, table, i, x0, v0, v1, w1, m, r, gravity, dt, k, d,
                                                 integrator, spinning)
        # integrate: symplectic Euler, x1 = x0 + dt v1
        x1 = x0 + dt * v1
        clearance -= (x1 - x0).norm()
        # scatter
        store(p, i, x0, v0, x1, v1, use_domain, domain_lo, domain_hi)
        if ti.static(spinning):
            if p.flags[i] != NON_FINITE:
                spin.w[i] = w1
    return clearance


#: Rounds of place_out's moves (a particle placed in a corner leaves one collider into another).
PLACED_ROUNDS = 4


@ti.kernel
def _place_out(particles: ParticleArgs, colliders: ColliderArgs, groups: ti.template(), first: ti.i32,
               stiffness: float, stiffness_per_mass: ti.i32, damping: float, damping_is_ratio: ti.i32, speed: float,
               # outputs
               moved: ARRAY):
    """Storage slots first.. at the colliders' start poses: a particle inside a collider by a
    depth whose undamped exit speed depth * sqrt(k/m) passes `speed` is moved out along the
    normal onto the surface, its velocity kept. moved[0]: 1 if any was."""
    for i in range(first, particles.count):
        if particles.flags[i] == ACTIVE:
            xi = particles.x[i]
            r = particles.radius[i]
            m = particles.mass[i]
            k, _d = contact_constants(m, stiffness, stiffness_per_mass, damping, damping_is_ratio)
            omega = ti.sqrt(k / m)
            out = False
            for _ in range(PLACED_ROUNDS):
                for ci in range(colliders.count):
                    if (xi - colliders.center0[ci]).norm() - colliders.params[ci][BOUND_SLOT] < r:
                        phi, n = collider_sdf(colliders, groups, ci, xi, False, r)
                        depth = r - phi
                        if depth * omega > speed:
                            xi += depth * n
                            out = True
            if out:
                particles.x[i] = xi
                moved[0] = 1


@functools.cache
def penalty_kernel(spinning: bool, loaded: bool):
    """The substep kernel for particles that spin or not (spin: types.SpinArgs), with loads
    from particle pairs or not (loads: Forces, or ForcesAndTorques for spinning particles)."""
    SpinType = SpinArgs if spinning else Unused
    LoadType = (ForcesAndTorques if spinning else Forces) if loaded else Unused

    @ti.kernel
    def penalty_substep(particles: ParticleArgs, colliders: ColliderArgs, groups: ti.template(), table: ARRAY,
                        n_substeps: ti.i32, gravity: vec3, dt: float, stiffness: float, stiffness_per_mass: ti.i32,
                        damping: float, damping_is_ratio: ti.i32, integrator: ti.i32, use_domain: ti.template(),
                        domain_lo: vec3, domain_hi: vec3, spin: SpinType, loads: LoadType):
        # Particles are independent: with colliders that hold still during the call, one
        # launch runs every substep of a particle in registers, carrying its clearance.
        for i in range(particles.count):
            clearance = -1.0
            for _ in range(n_substeps):
                clearance = penalty_particle(particles, colliders, groups, table, i, gravity, dt, stiffness,
                                             stiffness_per_mass, damping, damping_is_ratio, integrator, use_domain,
                                             domain_lo, domain_hi, clearance, spin, loads, spinning, loaded)

    return penalty_substep


class PenaltySolver(Solver):
    """Resolve particle-collider contacts with penalty forces (docs/physics.md 4, seed 002).

    A penetrating particle (depth = r - phi > 0) feels a zero-length spring-damper at the
    point of entry, f_n = k depth - D (v_rel . n), only pushing, with v_rel its velocity
    relative to the collider's surface. Friction is a force: Coulomb, static until the
    traction exceeds static_friction |f_n|, then kinetic friction |f_n| plus viscous
    wet_friction |f_n| |v_t| against the sliding (each collider's tc.Material). Colliders
    added with `repulsion=tc.RepulsionField(...)` also push at a distance.

    Give the stiffness one of two ways:
    stiffness: k in N/m, the same for every particle (heavier particles sink deeper); or
    hertz: the contact's natural frequency f in Hz, k = m (2 pi f)^2 per particle, so one
        setting gives every mass the same period 1/f and the same resting depth g/(2 pi f)^2.
    and the damping one of two ways (neither: critical damping):
    damping: D in N s/m, the same for every particle (0: undamped, elastic); or
    damping_ratio: zeta, D = 2 zeta sqrt(m k) per particle (1: critical, < 1 bouncy).
    integrator: "symplectic_euler" (default; explicit, accurate for dt well below the
        contact's smallest characteristic time, see `tc.params`) or "backward_euler" (the
        normal spring-damper implicit along n: stable at any dt, but it damps, so bounces
        lose height and resting depths are right while rebounds are not; friction and
        fields stay explicit).

    A contact that may only push cannot brake a particle on its way out: a critically
    damped one stops a particle without rebound while gravity does the last of the braking
    (impact speeds below about 30 g sqrt(m/k)); faster, it lets the particle leave at up to
    e^-2 = 13.5 % of its impact speed (damping_ratio 2: 4.8 %, 5: 0.9 %).

    spin: particles spin (False: they are points that slide). Each keeps an angular
        velocity (Scene.angular_velocities()) and is a solid sphere, I = 2/5 m r^2:
        friction acts at the contact point and turns the particle, so a sphere rolls down
        an incline at a = 5/7 g sin(theta) while static_friction >= 2/7 tan(theta), and a
        sphere thrown along a floor without spin slides, spins up and rolls on at 5/7 of
        its speed. The materials' rolling_friction mu_r resists rolling with a torque of at
        most mu_r r |f_n| (see spin_friction). Pairs between particles (DEM) then exchange
        torques too (solvers/pairs/dem.py). Beyond the lecture notes, whose particles are
        points: an extension for granular piles, which stand on rolling resistance
        (docs/physics.md 6). (`rotation` is its old name.)

    The scene warns once, before its first step, when dt exceeds 2x the recommended dt of
    its stiffest contact (its lightest particle); `contact_params(mass)` gives the numbers.
    The impulse solver's material fields apply here too (restitution is ignored: the
    bounce comes from the damping).
    """

    pair_model = "dem"

    @validate.renamed_arguments(rotation="spin")
    def __init__(self, *, stiffness: float | None = None, damping: float | None = None,
                 hertz: float | None = None, damping_ratio: float | None = None,
                 integrator: str = "symplectic_euler", spin: bool = False):
        if (stiffness is None) == (hertz is None):
            raise ValueError("give exactly one of stiffness (N/m) or hertz (Hz); "
                             f"got stiffness={stiffness!r}, hertz={hertz!r}")
        if damping is not None and damping_ratio is not None:
            raise ValueError("give at most one of damping (N s/m) or damping_ratio; "
                             f"got damping={damping!r}, damping_ratio={damping_ratio!r}")
        if not isinstance(spin, (bool, np.bool_)):
            raise TypeError(f"spin must be True or False; got {type(spin).__name__}")
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {tuple(INTEGRATORS)}; got {integrator!r}")
        self.stiffness = validate.real("stiffness", stiffness, low=0.0, low_open=True, allow_none=True)
        self.hertz = validate.real("hertz", hertz, low=0.0, low_open=True, allow_none=True)
        self.damping = validate.real("damping", damping, low=0.0, allow_none=True)
        self.damping_ratio = validate.real("damping_ratio", damping_ratio, low=0.0, allow_none=True)
        self.integrator = integrator
        self.spin = bool(spin)
        self._tables = weakref.WeakKeyDictionary()  # scene -> (key, per-collider ndarray)
        self._warned_overrun = set()  # ids of the collider entries warned about (_check_overrun)
        self._heaviest = None  # ((id of the particle store, its count), its heaviest mass in kg)

    def __repr__(self):
        k = f"stiffness={self.stiffness:g}" if self.stiffness is not None else f"hertz={self.hertz:g}"
        d = ("damping=critical" if self.damping is None and self.damping_ratio is None else
             f"damping={self.damping:g}" if self.damping is not None else f"damping_ratio={self.damping_ratio:g}")
        spin = ", spin=True" if self.spin else ""
        return f"PenaltySolver({k}, {d}, integrator={self.integrator!r}{spin})"

    # ---------------------------------------------------------------- constants
    def contact_stiffness(self, mass: float) -> float:
        """k (N/m) for a particle of this mass."""
        if self.stiffness is not None:
            return self.stiffness
        return params.stiffness_from_hertz(mass, self.hertz)

    def contact_damping(self, mass: float) -> float:
        """D (N s/m) for a particle of this mass."""
        if self.damping is not None:
            return self.damping
        ratio = 1.0 if self.damping_ratio is None else self.damping_ratio
        return params.damping_from_ratio(mass, self.contact_stiffness(mass), ratio)

    def contact_params(self, mass: float) -> params.ContactParams:
        """The 1-D contact model's numbers for a particle of this mass (tc.params.contact)."""
        return params.contact(mass, self.contact_stiffness(mass), self.contact_damping(mass))

    def _stiffest(self, world) -> params.ContactParams | None:
        """The contact with the smallest characteristic time: the lightest particle's, or with
        DEM pairs the two lightest particles' (reduced mass m / 2); the lightest of those added
        or that emitters will add (ParticleStore.mass_range)."""
        mass = world.particles.mass_range[0]
        if not np.isfinite(mass):  # (no particles, none to come)
            return None
        return self.contact_params(0.5 * mass if world.pair_contacts else mass)

    def _explicit(self, world) -> bool:
        """Whether some contact's spring is integrated explicitly: the colliders' (unless
        backward Euler) or DEM pairs' (always forces)."""
        return world.pair_contacts or (self.integrator != "backward_euler" and len(world.colliders) > 0)

    def time_step_limits(self, world) -> tuple | None:
        if not self._explicit(world):
            return None
        contact = self._stiffest(world)
        return None if contact is None else (contact.recommended_dt, contact.stability_limit)

    def check(self, world, dt: float) -> list[str]:
        """Warnings for the scene as it stands (called by Scene before stepping)."""
        if not self._explicit(world):
            return []
        contact = self._stiffest(world)
        if contact is None or dt <= WARN_FACTOR * contact.recommended_dt:
            return []
        return [f"PenaltySolver: dt = {dt:.3g} s is {dt / contact.recommended_dt:.1f}x the recommended "
                f"dt {contact.recommended_dt:.3g} s of the stiffest contact (k = {contact.stiffness:.4g} N/m, "
                f"m = {contact.mass:.4g} kg, D = {contact.damping:.4g} N s/m, {contact.regime}, natural period "
                f"{contact.natural_period:.3g} s, smallest characteristic time {contact.smallest_time:.3g} s); "
                f"explicit integration diverges beyond dt = {contact.stability_limit:.3g} s. Use "
                f"dt <= {contact.recommended_dt:.3g} s, a softer contact, or integrator='backward_euler'."]

    def place_out(self, world, first: int) -> None:
        """Particles placed from the host (storage slots first..) inside a collider so deep
        that its spring would throw them out faster than the pairs' default push speed
        (settings.MAX_PUSH_SPEED; depth * sqrt(k/m), undamped) are moved out onto its surface,
        their velocities kept (docs/physics.md 4.2): a penalty contact has no allowance for
        overlap placed against colliders, and the spring's energy k depth^2 / 2 would become
        speed. Shallower ones (a resting depth given on purpose) stay."""
        from .pairs.settings import MAX_PUSH_SPEED  # (here: the pairs package imports this module)

        particles = world.particles
        if particles.count <= first or not world.colliders.entries:
            return
        moved = ti.ndarray(ti.i32, shape=1)
        moved.fill(0)
        particles.mark_moved()
        _place_out(particles.args, world.colliders.args, world.colliders.groups, first, **self.contact_law(),
                   speed=MAX_PUSH_SPEED, moved=moved)
        if runtime.read_small(moved, 1)[0]:
            particles.edits += 1  # (positions changed outside the steps: kept lists no longer hold)

    def stability_advice(self, world) -> str | None:
        """What to change when a run went non-finite (Scene adds it to its error)."""
        contact = self._stiffest(world)
        if contact is None:
            return None
        return (f"the penalty contacts' recommended dt is {contact.recommended_dt:.3g} s (k = "
                f"{contact.stiffness:.4g} N/m, m = {contact.mass:.4g} kg, {contact.regime}; explicit integration "
                f"diverges beyond {contact.stability_limit:.3g} s)")

    # ---------------------------------------------------------------- stepping
    def _collider_table(self, colliders):
        """Friction coefficients and repulsion fields of the colliders (a ColliderTable), one
        row each, uploaded again only when colliders or their materials change."""
        entries = colliders.entries
        key = tuple((e.material, id(e.repulsion)) for e in entries)
        cached = self._tables.get(colliders)
        if cached is not None and cached[0] == key:
            return cached[1]
        rows = np.zeros((max(len(entries), 1), TABLE_WIDTH), dtype=runtime.float_dtype())
        for row, e in zip(rows, entries):
            m = e.material
            row[:] = (m.static_friction, m.friction, m.wet_friction, *pack(e.repulsion), m.rolling_friction)
        table = ti.Vector.ndarray(TABLE_WIDTH, float, shape=len(rows))
        table.from_numpy(rows)
        self._tables[colliders] = (key, table)
        return table

    def contact_law(self) -> dict:
        """The contact constants as kernels take them, by name: `stiffness` holds (2 pi f)^2
        when `stiffness_per_mass` (k = m (2 pi f)^2), `damping` holds zeta when
        `damping_is_ratio` (D = 2 zeta sqrt(m k))."""
        per_mass = self.stiffness is None
        stiffness = (2.0 * np.pi * self.hertz) ** 2 if per_mass else self.stiffness
        is_ratio = self.damping is None
        damping = (1.0 if self.damping_ratio is None else self.damping_ratio) if is_ratio else self.damping
        return dict(stiffness=stiffness, stiffness_per_mass=int(per_mass), damping=damping,
                    damping_is_ratio=int(is_ratio))

    def _check_overrun(self, world, dt: float):
        """Warn, once per collider, when a kinematic collider's surface is faster than its
        contacts can stop a particle within the particle's radius.

        Penalty forces act only on a particle that is already inside: struck at speed V, the
        softest contact (the heaviest particle's, with a stiffness in N/m) lets it sink up to
        V / w times impact_depth_factor(damping ratio). Deeper than the smallest radius, the
        particle's centre passes the surface, and it is pushed on through a thin collider or out
        of a thick one's far side; a surface that moves more than a radius in one substep can
        also step past a particle between two force evaluations. Continuous detection, which
        would catch both, belongs to tc.ImpulseSolver."""
        particles = world.particles
        if particles.count == 0:
            return
        if self._heaviest is None or self._heaviest[0] != (id(particles), particles.count):
            self._heaviest = ((id(particles), particles.count), float(np.max(particles.read("mass"))))
        contact = self.contact_params(self._heaviest[1])
        omega = math.sqrt(contact.stiffness / contact.mass)
        factor = impact_depth_factor(contact.damping_ratio)
        radius = particles.min_radius
        for index, entry in enumerate(world.colliders.entries):
            if not entry.is_kinematic or id(entry) in self._warned_overrun:
                continue
            if entry.shape.params[Collider.BOUND_SLOT] >= Collider.UNBOUNDED:
                # a plane: only its motion along the normal (the rotation's second column) strikes
                speed = abs(float(np.dot(entry.velocity, entry.rotation[:, 1])))
            else:
                speed = (float(np.linalg.norm(entry.velocity))
                         + float(np.linalg.norm(entry.angular_velocity)) * entry.shape.params[Collider.BOUND_SLOT])
            depth = speed / omega * factor
            if depth > radius or speed * dt > radius:
                self._warned_overrun.add(id(entry))
                hertz = speed * factor / (2.0 * math.pi * radius)
                notices.warn(
                    f"PenaltySolver: collider {index} ({type(entry.shape).__name__}) moves its surface at up to "
                    f"{speed:.3g} m/s. A penalty contact ({contact.regime}, natural period "
                    f"{contact.natural_period:.3g} s for m = {contact.mass:.3g} kg) lets a particle struck that fast "
                    f"sink up to {depth:.3g} m, and the surface moves {speed * dt:.3g} m in a substep of dt = "
                    f"{dt:.3g} s: beyond the smallest radius, {radius:.3g} m, particles pass through a thin "
                    f"collider or leave a thick one by its far side. Use a stiffer contact (natural frequency >= "
                    f"{hertz:.3g} Hz, with dt to match) or tc.ImpulseSolver, whose continuous detection follows a "
                    "moving collider", RuntimeWarning)

    def advance(self, world, dt: float, substeps: int = 1, loads=None):
        """Advance every active particle by `substeps` substeps of dt against the colliders,
        which must keep their current poses for the whole call. `loads`: optional per-particle
        loads held for the call (other particles'): Forces, or ForcesAndTorques when the
        particles spin."""
        particles = world.particles
        if world.colliders.has_kinematic:
            self._check_overrun(world, dt)
        if self.spin:
            particles.enable_spin()
        use_domain, lo, hi = world.domain_bounds()
        particles.mark_moved()
        kernel = penalty_kernel(self.spin, loads is not None)
        kernel(particles=particles.args, colliders=world.colliders.args, groups=world.colliders.groups,
               table=self._collider_table(world.colliders), n_substeps=substeps, gravity=host_vector(world.gravity), dt=dt,
               **self.contact_law(), integrator=INTEGRATORS[self.integrator], use_domain=use_domain,
               domain_lo=host_vector(lo), domain_hi=host_vector(hi), spin=particles.spin_args if self.spin else unused(),
               loads=loads if loads is not None else unused())

    def pair_substep(self, world, pairs, dt: float):
        """One substep with DEM pairs: their forces at the substep's start, then this solver's
        substep against the colliders with those forces."""
        pairs.dem_substep(world, self, dt)
