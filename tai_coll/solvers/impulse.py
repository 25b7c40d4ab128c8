"""Impulse-based contact resolution: docs/physics.md 3, the ways of putting collisions into
time integration. Each particle is resolved independently (in parallel) against the colliders.

One substep of one particle reads as: integrate without collisions to a candidate (x1, v1);
accept penetrations that were already there at time t and push out with the last-resort
repulsion; then resolve the candidate with the chosen scheme:

- "simple"          Implementation 1: one pass of the law on the average velocity.
- "micro"           Implementation 2: repeat while x1 interferes, e = 0 after the first pass.
- "elastic_contact" Implementation 3 (default): the elastic law on v(t), then inelastic
                    contact passes on the average velocity. Solves the bouncing-block problem.
- "exact_time"      Backing up time: advance to each first contact along the straight path,
                    apply the law there, continue for the rest of the substep. Closed form for
                    planes and spheres, root finding for the other shapes.

Loops are capped; a particle still interfering after the cap gets the failsafe: it stops
relative to the collider (v = surface velocity, x1 = x carried with the collider).

Every contact is taken relative to its collider (docs/physics.md 3.6): the kernels compile
that code in only for a collider table with moving colliders (`kinematic`), so still scenes
run the plain formulas.

One particle's query and response lives in resolve.py; this module holds the kernels that
run it (a launch of several substeps, and candidates from another phase) and the solver.
Kernels take the particle store and the collider table as argument packs (`p`, `c`:
types.ParticleArgs, types.ColliderArgs) and `groups`, the compile-time mask of the collider
kinds compiled in; the solver launches them with every argument named (`_law`).
"""


import taichi as ti

from .. import validate
from ..geometry import kinds
from ..response.exchange import body_law, held
from ..response.laws import WET_LAWS
from ..response.repulsion import RepulsionField, pack
from ..types import ACTIVE, ARRAY, NON_FINITE, ColliderArgs, ParticleArgs, host_vector, vec3
from .base import Solver
from .detection import keep_out, keep_out_of, surface_velocity
from .integrate import flag, state_status, store, symplectic_euler, try_flight_in_front, try_free_flight
from .lone_plane import lone_plane_substep
from .resolve import ELASTIC_CONTACT, SCHEMES, last_resort6, resolve_particle, resolve_passes

#: A particle's kept clearance when the last launch found it at a fixed point of its substep
#: (impulse_substep). Negative, so every other reader takes it for "unknown" and queries.
AT_REST = -2.0


@ti.kernel
def impulse_substep(particles: ParticleArgs, colliders: ColliderArgs, groups: ti.template(), kinematic: ti.template(),
                    clearances: ARRAY, separations: ARRAY, reuse_clearance: ti.i32, reuse_separation: ti.i32,
                    reuse_rest: ti.i32, n_substeps: ti.i32, gravity: vec3,
                    dt: float,
                    scheme: ti.template(), wet_law: ti.template(), max_iterations: ti.i32, elastic_iterations: ti.i32,
                    last_resort: last_resort6, max_push_speed: float, slop_fraction: float, rest_speed: float,
                    use_domain: ti.template(), domain_lo: vec3, domain_hi: vec3):
    """n_substeps substeps of every active particle against colliders that hold still for the
    call; `clearances` (one per particle, in-out) are kept between launches. kinematic: the
    table holds moving colliders (compile time: their relative-motion code is compiled in).

    Particles are independent of each other here, so one launch runs several substeps and
    keeps each particle in registers, including its clearance: a lower bound on how far it
    can travel before it could touch a collider (phi is 1-Lipschitz). While the clearance
    exceeds the path of the remaining substeps, nothing can be touched and those substeps are
    plain integration, done in closed form at once (free_flight). The clearance is reused
    from the last launch when the host says nothing moved in between: neither the colliders
    nor the particles outside this kernel (reuse_clearance).
    With still colliders a query also gives the nearest collider's separating plane (apart,
    level) and the other colliders' clearance (others), which let the particle fly in closed
    form while it stays in front of the plane (try_flight_in_front, docs/physics.md 3.7). They
    are kept in `separations` (one row per particle: apart, level, others less the particle's
    clearance, which free flight reduces by the same path, and the collider apart belongs to)
    for the next launch while the clearances this kernel wrote are the ones kept
    (reuse_separation). Where that collider is a plane and the others lie beyond the step, the
    substep takes the plane's short path (lone_plane.py, docs/physics.md 3.8).
    A substep that leaves a particle's state bit for bit as it was (a particle at rest on a
    still collider: gravity's dv cancelled by the contact, x1 = x0) would do exactly the same
    in every later substep of the launch, so the particle is done: an exact shortcut, not an
    approximation (no sleeping thresholds). Its clearance is then written as AT_REST, and the
    next launch skips it without reading its state when the host says that launch's substeps
    are the same map (reuse_rest: the clearances hold, and gravity, dt and the law are those of
    this launch): a fixed point of the same map stays one. The state stays in registers
    between substeps and is written once."""
    for i in range(particles.count):
        if particles.flags[i] == ACTIVE and not (reuse_rest and clearances[i] == AT_REST):
            x0 = particles.x[i]
            v0 = particles.v[i]
            clearance = -1.0
            if reuse_clearance:
                clearance = clearances[i]
            # the common case first, kept small: the whole launch in free flight
            flown, xk, vk, left = try_free_flight(x0, v0, clearance, gravity, dt, n_substeps, use_domain,
                                                  domain_lo, domain_hi)
            if flown:
                particles.x[i] = xk
                particles.v[i] = vk
                clearances[i] = left
                if ti.static(not kinematic):
                    if not reuse_separation:
                        # (the plane kept is not this clearance's: the next launch must not read it)
                        separations[i] = ti.Vector([0.0, 0.0, 0.0, 0.0, 0.0, -1.0])
            else:
                status = ACTIVE
                at_rest = False
                # Since the last query: the nearest collider's separating direction (zero: none)
                # and the level that apart . x must stay above for the particle to be clear of
                # it, and the clearance from the other colliders less the path since.
                apart = vec3(0.0, 0.0, 0.0)
                level = 0.0
                others = -1.0
                plane = -1  # the collider `apart` belongs to (-1: none, or not known)
                if ti.static(not kinematic):
                    if reuse_separation and clearance >= 0.0:
                        # the plane the last launch left, and the others' clearance, kept as
                        # its excess over the particle's clearance: free flight in between took
                        # the same path off both
                        kept = separations[i]
                        apart = vec3(kept[0], kept[1], kept[2])
                        level = kept[3]
                        others = clearance + kept[4]
                        plane = ti.cast(kept[5], ti.i32)
                s = 0
                while s < n_substeps:
                    planar = False
                    if ti.static(not kinematic):
                        planar = apart.norm_sqr() > 0.0
                    if planar:  # (the clearance was renewed by a query in this launch)
                        k, xk, vk, ahead, left = try_flight_in_front(x0, v0, apart, level, others, gravity, dt,
                                                                     n_substeps - s, use_domain, domain_lo,
                                                                     domain_hi)
                        if k > 0:
                            x0, v0, others, clearance = xk, vk, left, ti.min(ahead, left)
                            s += k
                            if s == n_substeps:
                                break
                    elif s > 0:  # the clearance may have been renewed by a query
                        flown, xk, vk, left = try_free_flight(x0, v0, clearance, gravity, dt, n_substeps - s,
                                                              use_domain, domain_lo, domain_hi)
                        if flown:
                            x0, v0, clearance = xk, vk, left
                            break
                    # one substep: free flight while the clearance lasts, else query and respond
                    x1, v1 = symplectic_euler(x0, v0, gravity, dt)
                    step = (x1 - x0).norm()
                    unchanged = False
                    clear_start = clearance >= 0.0  # (x0 is clear of every collider)
                    clear = False
                    if planar:
                        # In front of the nearest collider's plane at both ends of the straight
                        # step, and within the others' clearance: nothing to meet, however short
                        # the clearance around x0 (a particle rising off a floor). The clearance
                        # at x1 is the smaller of the two.
                        others -= step
                        ahead = apart.dot(x1) - level
                        clear = ahead > 0.0 and others > 0.0
                        clearance = ti.min(ahead, others)
                    elif ti.static(kinematic or groups != kinds.GROUP_ANALYTIC):
                        if clearance > step:
                            clear = True
                            clearance -= step
                    # (Still analytic tables: a substep without a separating plane queries. A
                    # query leaves a clear candidate as it is and finds the nearest collider's
                    # plane, which the launch then flies in front of in closed form; stepping
                    # through the clearance first costs a few substeps and queries all the same.)
                    if not clear:
                        done = False
                        if ti.static(not kinematic and scheme == ELASTIC_CONTACT):
                            # a lone still plane within reach (a floor): its own short path
                            # (lone_plane.py), which leaves anything else to the general scheme
                            if planar and clear_start and plane >= 0 and others >= step:
                                if colliders.kind[plane] == kinds.PLANE:
                                    r = particles.radius[i]
                                    done, x1, v1, clearance, apart, level, others = lone_plane_substep(
                                        colliders, plane, i, x0, v0, x1, v1, r, slop_fraction * r, dt,
                                        elastic_iterations, others, wet_law)
                        if not done:
                            x1, v1, clearance, apart, level, others, plane, _push = resolve_particle(
                                particles, colliders, groups, kinematic, i, x0, v0, x1, v1, dt, scheme, wet_law,
                                max_iterations, elastic_iterations, last_resort, max_push_speed, slop_fraction,
                                rest_speed, clear_start)
                        unchanged = all(x1 == x0) and all(v1 == v0)
                    status = state_status(x1, v1, use_domain, domain_lo, domain_hi)
                    if status == NON_FINITE:
                        break  # frozen at its last finite state
                    x0 = x1
                    v0 = v1
                    s += 1
                    if status != ACTIVE or unchanged:
                        at_rest = unchanged and status == ACTIVE
                        break
                particles.x[i] = x0
                particles.v[i] = v0
                clearances[i] = clearance
                if ti.static(not kinematic):
                    if clearance < 0.0:
                        apart = vec3(0.0, 0.0, 0.0)  # (read only with a clearance >= 0)
                    separations[i] = ti.Vector([apart[0], apart[1], apart[2], level, others - clearance,
                                                ti.cast(plane, float)])
                if at_rest:
                    clearances[i] = AT_REST
                if status != ACTIVE:
                    flag(particles, i, status)


@ti.kernel
def impulse_resolve_candidates(particles: ParticleArgs, colliders: ColliderArgs, groups: ti.template(),
                               kinematic: ti.template(), clearances: ARRAY, reuse_clearance: ti.i32, dt: float,
                               scheme: ti.template(), wet_law: ti.template(), max_iterations: ti.i32,
                               elastic_iterations: ti.i32, last_resort: last_resort6, max_push_speed: float,
                               slop_fraction: float, rest_speed: float, use_domain: ti.template(), domain_lo: vec3,
                               domain_hi: vec3,
                               contact_only: ti.template(), store_state: ti.template(), allow: ti.template(),
                               # out: the largest push granted as allowance (allow)
                               pushed: ARRAY,
                               # in-out
                               candidate_x: ARRAY, candidate_v: ARRAY):
    """Resolve candidates that another phase (particle-particle contacts) produced: with the
    chosen scheme, or with contact passes only (e = 0) when contact_only; then either store
    them as the new state, or write them back as candidates for the next phase. A particle
    whose kept clearance (see impulse_substep) exceeds the way from x to its candidate
    cannot touch a collider: it is left as it is, without a query; so is a sleeping one.
    Candidates written back (not store_state) whose start lay inside a collider have the last
    resort's push moved into their start (x), which the later phases integrate from, and with
    `allow` it is also overlap allowance with their neighbours (pushed[0]: the largest)."""
    for i in range(particles.count):
        resolve_candidate(particles, colliders, groups, kinematic, i, clearances, reuse_clearance, candidate_x,
                          candidate_v, dt, scheme, wet_law, max_iterations, elastic_iterations, last_resort,
                          max_push_speed, slop_fraction, rest_speed, use_domain, domain_lo, domain_hi, contact_only,
                          store_state, allow, pushed)


@ti.kernel
def store_out_of_bodies(particles: ParticleArgs, colliders: ColliderArgs, groups: ti.template(),
                        wet_law: ti.template(), allow: ti.template(), use_domain: ti.template(), domain_lo: vec3,
                        domain_hi: vec3, candidate_x: ARRAY, candidate_v: ARRAY) -> float:
    """Store the candidates as the new state, each kept out of the rigid bodies at the poses
    they were committed to (the table's end poses; their start poses are the substep's):
    after the particles' last collider passes and the bodies' own end of the substep
    (docs/physics.md 7.2). A body that went further than its particles (split among more
    particles than met it, it was slowed less than they saw) has moved them: each particle
    it pushes out meets it, inelastically, with the two-body law, and books the impulse in
    the ledger (BodySystem.take_pushes takes it from the body). allow: the push is an error
    of the body's position, not a blow, and becomes overlap allowance (m) with the
    particle's neighbours (which the pair passes then remove by positions, at their push
    speed, docs/physics.md 5.2.1). A particle held by its supports (shock propagation), or
    that the push would put into a collider that is not a body, is left where it is: the body
    stopped on it (BodySystem.end), and the depth is the body's. Returns the longest push (m).
    (The clearances are left unwritten: the store's version moves on, so none is trusted.)"""
    longest = 0.0
    for i in range(particles.count):
        if particles.flags[i] == ACTIVE:
            x0 = particles.x[i]
            x1 = candidate_x[i]
            v1 = candidate_v[i]
            r = particles.radius[i]
            pushed = 0.0
            for ci in range(colliders.count):
                if colliders.body[ci] >= 0:
                    x_kept = keep_out_of(colliders, groups, True, ci, x0, x1, r)
                    out = x_kept - x1
                    length = out.norm()
                    if length > 0.0:
                        n = out / length
                        point = x_kept - r * n
                        vs = surface_velocity(colliders, ci, point)
                        if not held(colliders, i, n, v1, vs) and all(
                                keep_out(colliders, groups, True, x0, x_kept, r) == x_kept):
                            x1 = x_kept
                            pushed += length
                            v1, _ = body_law(colliders, ci, i, 1.0 / particles.mass[i], x1, v1, n, vs, point, 0.0,
                                             0.0, wet_law)
            if pushed > 0.0:
                ti.atomic_max(longest, pushed)
                if ti.static(allow):
                    particles.allowance[i] = particles.allowance[i] + pushed
            store(particles, i, x0, particles.v[i], x1, v1, use_domain, domain_lo, domain_hi)
    return longest


@ti.func
def resolve_candidate(p: ti.template(), c: ti.template(), groups: ti.template(), kinematic: ti.template(), i,
                      clearances: ti.template(), reuse_clearance, candidate_x: ti.template(),
                      candidate_v: ti.template(), dt,
                      scheme: ti.template(), wet_law: ti.template(), max_iterations, elastic_iterations, last_resort,
                      max_push_speed, slop_fraction, rest_speed, use_domain: ti.template(), domain_lo: vec3,
                      domain_hi: vec3, contact_only: ti.template(), store_state: ti.template(),
                      allow: ti.template(), pushed: ti.template()):
    if p.flags[i] == ACTIVE:
        x0 = p.x[i]
        v0 = p.v[i]
        x1 = candidate_x[i]
        v1 = candidate_v[i]
        way = (x1 - x0).norm()
        clearance = -1.0
        if reuse_clearance:
            clearance = clearances[i]
        if clearance > way or p.rest[i] < 0.0:
            # out of every collider's reach, or asleep (its candidate is where it rests: the
            # pair passes move no sleeping particle, and colliders hold still while particles
            # sleep, docs/physics.md 5.3.1): nothing to resolve
            clearance -= way
        else:
            if ti.static(contact_only):
                r = p.radius[i]
                x1, v1, clearance, apart, level, others, _near = resolve_passes(
                    p, c, groups, kinematic, i, 1.0 / p.mass[i], x0, vec3(0.0, 0.0, 0.0), v0, x1, v1, r,
                    slop_fraction * r, dt, 0, max_iterations, False, True, wet_law)
                x_kept = keep_out(c, groups, kinematic, x0, x1, r)
                if any(x_kept != x1):
                    clearance = -1.0
                    # A position kept out of a collider keeps no velocity into it either: the
                    # contact passes leave motion within the slop alone, and a particle held
                    # against a collider would otherwise carry the push of its neighbours on as
                    # velocity.
                    out = x_kept - x1
                    into = v1.dot(out)
                    if into < 0.0:
                        v1 -= (into / out.norm_sqr()) * out
                x1 = x_kept
            else:
                x1, v1, clearance, apart, level, others, _nearest, push = resolve_particle(
                    p, c, groups, kinematic, i, x0, v0, x1, v1, dt, scheme, wet_law, max_iterations,
                    elastic_iterations, last_resort, max_push_speed, slop_fraction, rest_speed, clearance >= 0.0)
                if ti.static(not store_state):
                    if any(push != 0.0):
                        # The last resort's push moves the position only (docs/physics.md 3.4):
                        # it moves the start of the substep, which the later phases integrate
                        # from (the pairs' contact passes, the colliders' contact passes), so
                        # that they keep it; with `allow` the overlap it pushes the particle
                        # into is placed overlap, removed by positions (docs/physics.md 5.2.1)
                        p.x[i] = x0 + push
                        if ti.static(allow):
                            length = push.norm()
                            p.allowance[i] = p.allowance[i] + length
                            ti.atomic_max(pushed[0], length)
        if ti.static(store_state):
            store(p, i, x0, v0, x1, v1, use_domain, domain_lo, domain_hi)
            clearances[i] = clearance
        else:
            candidate_x[i] = x1
            candidate_v[i] = v1


class ImpulseSolver(Solver):
    """Resolve particle-collider contacts with impulses (docs/physics.md 2 and 3).

    scheme: "elastic_contact" (default, Implementation 3), "micro" (Implementation 2),
        "simple" (Implementation 1, kept for comparison: it fails for resting contact) or
        "exact_time" (backing up time; exact for planes and spheres).
    max_iterations: cap on the contact passes (and on events per substep for exact_time)
        before the failsafe. More passes resolve corners better and cost time in contact.
    elastic_iterations: how many times the elastic pass of Implementation 3 may repeat
        while the candidate still interferes.
    push_fraction: the last resort for a particle already inside a collider at the start of
        a substep: this fraction of the depth is recovered per substep, by moving the position
        along the normal (the velocity gets the inelastic law), at most max_push_speed * dt
        per substep.
    max_push_speed: m/s, the cap on that push.
    last_resort: None (the push above) or a `tc.RepulsionField` acting instead on the
        velocity of a particle found inside, at gap -depth (seed 002). A velocity field of
        strength s lets it leave at s m/s or more, a force field accelerates it out.
        Colliders' own repulsion fields (`add_collider(repulsion=...)`) are for the penalty
        solver; this solver ignores them, with a warning.
    slop: penetration, as a fraction of the particle radius, below which a particle still
        counts as outside (absorbs round-off at resting contacts).
    rest_speed: exact_time only: approach speeds (m/s) below this get e = 0. None: twice the
        speed gravity adds in one substep.
    wet_law: "linear" max(0, 1 - D dv_N) or "exponential" exp(-D dv_N) (seed 001).
    (`repulsion` and `repulsion_speed_limit` are the old names of push_fraction and
    max_push_speed.)
    """

    pair_model = "impulses"

    @validate.renamed_arguments(repulsion="push_fraction", repulsion_speed_limit="max_push_speed")
    def __init__(self, *, scheme: str = "elastic_contact", max_iterations: int = 8,
                 elastic_iterations: int = 1, push_fraction: float = 0.1, max_push_speed: float = 1.0,
                 slop: float = 1e-3, rest_speed: float | None = None, wet_law: str = "linear",
                 last_resort: RepulsionField | None = None):
        if scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {tuple(SCHEMES)}; got {scheme!r}")
        if wet_law not in WET_LAWS:
            raise ValueError(f"wet_law must be one of {tuple(WET_LAWS)}; got {wet_law!r}")
        self.scheme = scheme
        self.max_iterations = validate.integer("max_iterations", max_iterations, low=1)
        self.elastic_iterations = validate.integer("elastic_iterations", elastic_iterations, low=0)
        self.push_fraction = validate.real("push_fraction", push_fraction, low=0.0, high=1.0, low_open=True)
        self.max_push_speed = validate.real("max_push_speed", max_push_speed, low=0.0, low_open=True)
        self.slop = validate.real("slop", slop, low=0.0, high=0.5)
        self.rest_speed = validate.real("rest_speed", rest_speed, low=0.0, allow_none=True)
        self.wet_law = wet_law
        if last_resort is not None and not isinstance(last_resort, RepulsionField):
            raise TypeError(f"last_resort must be None or a tc.RepulsionField; got {type(last_resort).__name__}")
        self.last_resort = last_resort

    def __repr__(self):
        return f"ImpulseSolver(scheme={self.scheme!r}, max_iterations={self.max_iterations})"

    def check(self, world, dt: float) -> list[str]:
        """Warnings for the scene as it stands (called by Scene before stepping)."""
        fielded = [k for k, e in enumerate(world.colliders.entries) if e.repulsion is not None]
        if not fielded:
            return []
        return [f"ImpulseSolver ignores the repulsion fields of colliders {fielded}; they act with "
                "tc.PenaltySolver. ImpulseSolver(last_resort=tc.RepulsionField(...)) uses one as its last resort."]

    def _law(self, world, dt: float) -> dict:
        """The kernels' scheme, law and domain arguments, by name."""
        rest_speed = self.rest_speed if self.rest_speed is not None else world.rest_speed(dt)
        use_domain, lo, hi = world.domain_bounds()
        return dict(scheme=SCHEMES[self.scheme], wet_law=WET_LAWS[self.wet_law], max_iterations=self.max_iterations,
                    elastic_iterations=self.elastic_iterations,
                    last_resort=host_vector((self.push_fraction, *pack(self.last_resort))),
                    max_push_speed=self.max_push_speed, slop_fraction=self.slop, rest_speed=rest_speed,
                    use_domain=use_domain, domain_lo=host_vector(lo), domain_hi=host_vector(hi))

    def resolve_candidates(self, world, dt: float, candidate_x, candidate_v, *, contact_only=False,
                           store_state=True, pushed=None):
        """Resolve candidate positions and velocities (arrays) from another phase against the
        colliders: with the scheme, or contact passes only; store the result as the
        particles' new state, or write it back to the candidate arrays. pushed: None, or a
        one-element array (zeroed) into which the largest last-resort push goes, each push
        granted as overlap allowance (the pairs' placed overlap, docs/physics.md 5.2.1)."""
        store, table = world.particles, world.colliders
        reuse = store.clearances_hold(table)
        if store_state:
            store.mark_moved()
        impulse_resolve_candidates(particles=store.args, colliders=table.args, groups=table.groups,
                                   kinematic=table.has_kinematic, clearances=store.clearance,
                                   reuse_clearance=int(reuse), dt=dt,
                                   **self._law(world, dt), contact_only=contact_only, store_state=store_state,
                                   allow=pushed is not None, pushed=store.clearance if pushed is None else pushed,
                                   candidate_x=candidate_x, candidate_v=candidate_v)
        if store_state:
            store.clearances_written(table)

    def store_out_of_bodies(self, world, candidate_x, candidate_v, allow: bool) -> float:
        """Store candidates that resolve_candidates(store_state=False) left, kept out of the
        rigid bodies at their committed poses (the table's end poses: bodies/system.py,
        BodySystem.end with in_table); allow: pushes become overlap allowances. Returns the
        longest push (m)."""
        store, table = world.particles, world.colliders
        use_domain, lo, hi = world.domain_bounds()
        store.mark_moved()
        return store_out_of_bodies(particles=store.args, colliders=table.args, groups=table.groups,
                                   wet_law=WET_LAWS[self.wet_law], allow=allow, use_domain=use_domain,
                                   domain_lo=host_vector(lo), domain_hi=host_vector(hi), candidate_x=candidate_x,
                                   candidate_v=candidate_v)

    def advance(self, world, dt: float, substeps: int = 1):
        """Advance every active particle by `substeps` substeps of dt against the colliders,
        which must keep their current poses for the whole call."""
        store, table = world.particles, world.colliders
        reuse = store.clearances_hold(table)
        law = self._law(world, dt)
        # the map one substep applies: particles at a fixed point of it stay there (AT_REST)
        same_map = (tuple(map(float, world.gravity)), float(dt), self.scheme, self.wet_law, self.max_iterations,
                    self.elastic_iterations, self.push_fraction, self.max_push_speed, self.slop,
                    float(law["rest_speed"]), repr(self.last_resort), repr(world.domain))
        reuse_rest = reuse and store.rest_map == same_map
        # the separating planes this kernel kept hold while the clearances it wrote are kept
        reuse_separation = reuse and store.separation_key == store.clearance_key
        store.mark_moved()
        impulse_substep(particles=store.args, colliders=table.args, groups=table.groups,
                        kinematic=table.has_kinematic, clearances=store.clearance, separations=store.separation,
                        reuse_clearance=int(reuse), reuse_separation=int(reuse_separation),
                        reuse_rest=int(reuse_rest), n_substeps=substeps,
                        gravity=host_vector(world.gravity), dt=dt, **law)
        store.clearances_written(table)
        store.separation_key = store.clearance_key
        store.rest_map = same_map

    def pair_substep(self, world, pairs, dt: float):
        """One substep with particle-particle impulses, the colliders resolved by this solver."""
        pairs.impulse_substep(world, self, dt)
