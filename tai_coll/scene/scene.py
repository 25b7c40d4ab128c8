"""Scene assembly: particles, colliders, a solver, and the frame loop."""

from __future__ import annotations

import dataclasses

import numpy as np

from .. import export, notices, runtime, serial_loops, validate
from ..bodies.body import Body
from ..bodies.mass_properties import mass_properties
from ..bodies.system import BodyMotion, BodySystem
from ..errors import SimulationError
from ..geometry.colliders import Collider
from ..materials import Material
from ..neighbors.hash_grid import MAX_LISTED, NEIGHBOUR_CAPACITY
from ..response.repulsion import RepulsionField
from ..solvers import ImpulseSolver, Solver, World
from ..solvers.pairs import PairSettings, ParticleCollisions
from ..types import STATUS_NAMES
from . import checkpoint
from .colliders import ColliderEntry, ColliderTable
from .emitters import Emitter, Sinks, emit, remove_marked
from .motion import make_motion
from .particles import ParticleStore
from .stepping import DEFAULT_SUBSTEPS, DIVERGED_FACTOR, DIVERGED_SPEED, SubstepChoice

# DEM pairs overlapping by more than this fraction of the smaller radius are warned about: the
# contacts are too soft for their load (piles at sensible stiffness overlap a few per cent).
CRUSHED_OVERLAP = 0.25


@runtime.bound_to_runtime
class Scene:
    """Particles, the colliders they hit, and how contacts are resolved.

    gravity: acceleration in m/s^2 applied to every particle.
    dt: substep length in seconds (> 0; default 1/600, or frame_dt / substeps).
    substeps: substeps per frame (>= 1; default 10): one `step()` advances one frame of
        substeps * dt seconds. Or "auto": every frame of frame_dt seconds (default 1/60) is cut
        into as many equal substeps as the scene needs right then (docs/physics.md 3): the
        solver's stability limit (the stiffest penalty contact's recommended dt, tc.params)
        and a travel limit (no particle or point of a body moves more than `cfl` of the
        smallest radius in a substep, gravity's acceleration included), at most `max_substeps`
        (default 1000) and no longer than `dt` if given; `stats()` reports each frame's choice.
    solver: how contacts are resolved; default `ImpulseSolver()` (elastic, then contact);
        `PenaltySolver(...)` resolves them with forces instead.
    domain: optional ((x0, y0, z0), (x1, y1, z1)) box in m. A particle that leaves it is
        frozen where it left and no longer simulated (see `particle_status()`), with a warning.

    After tc.init restarts Taichi, every public method raises RuntimeError
    (runtime.bound_to_runtime): the scene's arrays died with the old runtime.
    """

    def __init__(self, *, gravity=(0.0, -9.81, 0.0), dt: float | None = None, substeps: int | str = DEFAULT_SUBSTEPS,
                 frame_dt: float | None = None, max_substeps: int | None = None, cfl: float | None = None,
                 solver=None, domain=None):
        self._runtime = runtime.ensure_init()
        gravity = validate.vector3("gravity", gravity)
        self._stepping = SubstepChoice.build(dt, substeps, frame_dt, max_substeps, cfl)
        self.dt, self.substeps = self._stepping.initial
        self.solver = solver if solver is not None else ImpulseSolver()
        if isinstance(self.solver, type):
            raise TypeError(f"solver must be a solver instance such as tc.ImpulseSolver(); got the class "
                            f"{self.solver.__name__} itself: pass an instance, {self.solver.__name__}(...)")
        if not isinstance(self.solver, Solver):
            raise TypeError(f"solver must be a solver such as tc.ImpulseSolver(); got {type(self.solver).__name__}")
        domain = None if domain is None else validate.box("domain", domain)
        self._particles = ParticleStore()
        self._colliders = ColliderTable()
        self._bodies = BodySystem(self._colliders)  # rigid bodies (bodies/system.py)
        # what the solver is handed each call (solvers/base.py)
        self._world = World(particles=self._particles, colliders=self._colliders, gravity=gravity, domain=domain,
                            bodies=self._bodies)
        self._pairs = None  # particle-particle collisions, off until enabled
        self._body_handles = []
        self._emitters = []  # sources of particles (emitters.py), in the order added
        self._sinks = Sinks()  # regions that remove particles
        self._frame = 0  # frames stepped (save_state keeps it; frames written are numbered by it)
        self._time_base = 0.0  # time when dt last changed (substeps="auto")
        self._substep_count = 0  # substeps of dt since then
        self._substep_limit = "fixed" if not self._stepping.auto else "frame_dt"  # what set dt (stats)
        self._watch = None  # (speed bound, since when): dt is beyond the stability limit (_check_solver)
        self._limits = None  # the solver's (recommended dt, stability limit), or None (_check_solver)
        self._solver_checked = None  # (particles, colliders) when the solver last checked the scene
        self._solver_warned = set()
        self._placed_checked = None  # the store's placements when placed particles were last moved out
        self._warned_dropped = False  # whether full neighbour lists were warned about (once)
        self._warned_crushed = False  # whether DEM overlap beyond CRUSHED_OVERLAP was warned about (once)

    # ---------------------------------------------------------------- building
    def add_collider(self, collider: Collider, *, material: Material | None = None, velocity=None,
                     angular_velocity=None, motion=None, repulsion: RepulsionField | None = None) -> ColliderEntry:
        """Add a collider. Kinematic motion, if any: a constant `velocity` (m/s) and
        `angular_velocity` (rad/s, about the collider's center), or `motion`, a callable
        t -> (translation, rotation_matrix) applied to the collider's rest pose.
        repulsion: a `tc.RepulsionField` pushing particles away before they touch (the
        penalty solver applies it). Returns the scene's entry for it (current pose,
        material, velocities)."""
        if not isinstance(collider, Collider):
            raise TypeError(f"collider must be a tai_coll collider (Plane, Sphere, Box, ...); "
                            f"got {type(collider).__name__}")
        if material is None:
            material = Material()
        elif not isinstance(material, Material):
            raise TypeError(f"material must be a tc.Material; got {type(material).__name__}")
        if repulsion is not None and not isinstance(repulsion, RepulsionField):
            raise TypeError(f"repulsion must be a tc.RepulsionField; got {type(repulsion).__name__}")
        motion = make_motion(velocity, angular_velocity, motion)
        entry = self._colliders.add(collider, material, motion, self.time)
        entry.repulsion = repulsion
        return entry

    def add_body(self, shape: Collider, *, mass=None, density=None, inertia=None, material: Material | None = None,
                 velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0)) -> Body:
        """Add a rigid body (docs/physics.md 7): a closed collider shape (Sphere, Box, Cylinder,
        Capsule, a closed TriangleMesh or a MeshSDF of a closed mesh) with mass, placed where
        the shape is. Its position is its centre of mass (a mesh's from its volume).
        Exactly one of mass (kg) or density (kg/m^3), > 0. inertia: a 3x3 tensor (kg m^2)
        about the centre of mass in the shape's local axes, symmetric positive definite
        (default: the shape's at uniform density). material: its restitution and friction
        against particles (as a collider's), colliders and other bodies. velocity (m/s) of
        the centre of mass and angular_velocity (rad/s), world frame. Particles push it and
        it pushes back (both solvers); it falls under gravity and collides with colliders
        and other bodies. Returns the tc.Body."""
        if not isinstance(shape, Collider):
            raise TypeError(f"shape must be a closed tai_coll collider (Sphere, Box, Cylinder, Capsule, "
                            f"TriangleMesh, MeshSDF); got {type(shape).__name__}")
        props = mass_properties(shape, mass=mass, density=density, inertia=inertia)  # (refuses open shapes)
        if material is None:
            material = Material()
        elif not isinstance(material, Material):
            raise TypeError(f"material must be a tc.Material; got {type(material).__name__}")
        velocity = validate.vector3("velocity", velocity)
        angular_velocity = validate.vector3("angular_velocity", angular_velocity)
        store = self._bodies.store
        motion = BodyMotion(store, store.count)
        entry = self._colliders.add(shape, material, None, self.time)
        entry.motion = motion  # (the body's motion, once the store holds it)
        store.add(entry, material, props, shape.rotation.copy(), velocity, angular_velocity)
        entry.center, entry.rotation = store.shape_pose(motion.index)
        handle = Body(self._bodies, motion.index)
        self._body_handles.append(handle)
        self._solver_checked = None
        return handle

    @property
    def bodies(self) -> list[Body]:
        """The rigid bodies, in the order they were added."""
        return list(self._body_handles)

    def add_particles(self, *, positions, velocities=None, mass=1.0, radius=0.005) -> slice:
        """Add particles. positions, velocities: (N, 3) in m and m/s (velocities default 0);
        mass (kg) and radius (m): a scalar or an (N,) array, > 0. Returns their index slice."""
        x = validate.points("positions", positions)
        n = len(x)
        if velocities is None:
            v = np.zeros_like(x)
        else:
            v = validate.points("velocities", velocities)
            if v.shape != x.shape:
                raise ValueError(f"velocities must have the shape of positions {x.shape}; got {v.shape}")
        m = validate.per_item("mass", mass, n)
        r = validate.per_item("radius", radius, n)
        return self._particles.add(x, v, m, r)

    def add_emitter(self, region, *, rate, velocity=(0.0, 0.0, 0.0), radius=0.005, mass=1.0, start=0.0,
                    stop=None, max_particles=None, seed=0) -> Emitter:
        """Emit particles (docs/physics.md 8): at the start of every substep, the particles due
        by its end at `rate` per second from time `start` (s) until `stop` (None: no end), at
        most `max_particles` in all, each placed at a random point of `region` (a tc.Box,
        tc.Sphere or tc.Cylinder, read as a volume) where it overlaps no particle, no other
        new one and no collider, with `velocity` (m/s), `radius` (m) and `mass` (kg). Where
        the region has no room it emits fewer and counts the rest as skipped. The same `seed`
        gives the same particles. Returns the tc.Emitter (emitted, skipped)."""
        emitter = Emitter(region, rate=rate, velocity=velocity, radius=radius, mass=mass, start=start, stop=stop,
                          max_particles=max_particles, seed=seed)
        self._emitters.append(emitter)
        self._particles.expect(emitter.mass, emitter.radius)  # (grids, substeps and the solver's check see them coming)
        self._solver_checked = None
        return emitter

    def add_sink(self, region) -> None:
        """Remove particles whose centre enters `region` (a tc.Box, tc.Sphere or tc.Cylinder,
        read as a volume): checked after every substep, removed at the end of the frame
        (docs/physics.md 8). Their ids are never given out again."""
        self._sinks.add(region)

    @property
    def emitters(self) -> list[Emitter]:
        """The emitters, in the order they were added."""
        return list(self._emitters)

    @property
    def sinks(self) -> list:
        """The sinks' regions, in the order they were added."""
        return list(self._sinks.regions)

    def enable_particle_collisions(self, *, material: Material | None = None, **options) -> ParticleCollisions:
        """Let particles collide with each other (docs/physics.md 5): impulses between pairs
        found by a spatial hash grid each substep, with restitution and friction from
        `material`, then the colliders. With a tc.PenaltySolver, pairs are DEM spring-dashpots
        with the solver's stiffness and damping (reduced mass) and the material's friction.
        Options (solvers.pairs.PairSettings): method ("gauss-seidel", the default, or
        "jacobi": how the passes visit the pairs), iterations (contact passes, default 1
        Gauss-Seidel, 4 Jacobi), projection_iterations (3 / 4), relaxation (1.0 / 1.5),
        contact_margin (m; None: a quarter of each pair's smaller radius), verlet_skin (m; 0: extra
        reach that lets neighbour lists be kept between substeps), reorder (True: the store
        kept in the grid's cell order; public order never changes), tangential_springs (False;
        DEM pairs only: friction by a spring per contact, Cundall and Strack, so static friction
        holds without creeping), tangential_ratio (2/7: k_t / k_n), max_push_speed (m/s, 0.5:
        overlap particles were placed with goes by positions at this speed) and, Gauss-Seidel
        only, sleep_time (s; "auto", the default: 0.3; None: no sleeping), sleep_drift (0.3
        radii) and wake_speed (m/s, 0.05): particles at rest that long fall asleep
        (docs/physics.md 5.3.1). With
        tc.PenaltySolver(spin=True) pairs also exchange torques: friction acts at the contact
        point and the material's rolling_friction resists rolling (a rolling spring per
        contact with tangential_springs). Returns the scene's ParticleCollisions (settings and
        counters)."""
        settings = PairSettings(material=material, **options)
        if self._particles.count > MAX_LISTED:
            raise ValueError(f"particle collisions hold at most {MAX_LISTED:,} particles (their neighbour lists' "
                             f"limit, Taichi's 32-bit array offsets); this scene has {self._particles.count:,}")
        if settings.tangential_springs and self.solver.pair_model != "dem":
            raise ValueError("tangential_springs: DEM pairs only (the scene's solver must be a tc.PenaltySolver; "
                             f"got {type(self.solver).__name__}, whose pair impulses hold statically already)")
        self._pairs = ParticleCollisions(settings)
        self._particles.max_count = MAX_LISTED
        self._particles.wake_all()
        self._world = dataclasses.replace(self._world, pair_contacts=True)
        self._warned_dropped = self._warned_crushed = False
        self._solver_checked = None  # pair contacts can be the stiffest
        return self._pairs

    @property
    def particle_collisions(self) -> ParticleCollisions | None:
        """The particle collisions enable_particle_collisions turned on (settings and
        counters), or None."""
        return self._pairs

    def particle_overlap(self) -> dict:
        """Overlap between touching particles now, relative to the smaller radius of each
        pair: {"max", "mean" (over overlapping pairs), "pairs"}; all 0 without particles."""
        if not self._particles.count:  # (no particles: no grid cell size to sort them by)
            return {"max": 0.0, "mean": 0.0, "pairs": 0}
        pairs = self._pairs if self._pairs is not None else ParticleCollisions(PairSettings())
        return pairs.overlap(self._world)

    def state_nbytes(self) -> int:
        """Bytes of every per-particle array the scene holds: the particle store and, with
        particle collisions, the pair solver's work arrays, grid, lists and springs; with
        rigid bodies, the ledger of what particles give them (docs/physics.md 7.2)."""
        held = self._particles.arrays() + (self._pairs.arrays() if self._pairs is not None else [])
        held += self._bodies.coupling.arrays()
        return int(sum(a.to_numpy().nbytes for a in held))

    # ---------------------------------------------------------------- running
    def step(self, frames: int = 1) -> None:
        """Advance `frames` frames of `substeps` substeps of `dt` seconds."""
        frames = validate.integer("frames", frames, low=0)
        # a small scene launches serial kernels on the CPU (tai_coll/serial_loops.py)
        info = runtime.ensure_init()
        with serial_loops.small(self.num_particles, info.arch == "cpu", info.threads):
            self._step(frames)

    def _step(self, frames: int) -> None:
        kinematic = self._colliders.has_kinematic
        sinks = len(self._sinks) > 0
        emitting = bool(self._emitters)
        for _ in range(frames):
            self._check_solver()
            self._place_out()
            if self._stepping.auto:
                self._choose_substeps()
            world = self._world
            bodies = self._bodies if self._bodies.count else None
            if bodies is not None and self.num_particles:
                bodies.warn_travel(self.dt, self._particles.min_radius, self.time)
            if self._pairs is not None or kinematic or sinks or emitting:
                # Particles interact, colliders move (bodies among them: new poses before every
                # substep), particles enter or leave: every substep is its own sequence of phases.
                for _ in range(self.substeps):
                    if emitting:  # (particles due by the substep's end)
                        emit(self._emitters, self._particles, self._sinks, self._colliders.entries, self.time + self.dt,
                             self.dt)
                    pairs = self._pairs is not None and self._particles.count
                    if kinematic:
                        self._colliders.advance(self.time, self.dt)
                    if bodies is not None:
                        bodies.begin(world, self.dt)
                    if pairs:
                        self.solver.pair_substep(world, self._pairs, self.dt)
                    else:
                        self.solver.advance(world, self.dt, 1)
                    if bodies is not None and bodies.open:  # (unless the particles' substep ended it)
                        bodies.end(world, self.dt)
                    if sinks and self._particles.count:
                        self._sinks.mark(self._particles)
                    self._substep_count += 1
            else:
                self.solver.advance(world, self.dt, self.substeps)
                self._substep_count += self.substeps
            if bodies is not None:
                self._colliders.commit_poses()  # the table at the bodies' poses between frames
            if sinks:
                remove_marked(self._particles, self._sinks, self._pairs)
            self._frame += 1
            self._check_health()

    def _check_solver(self):
        """Let the solver look at the scene before it steps (the penalty solver compares dt
        with its stiffest contact) whenever particles or colliders were added; each
        warning is given once."""
        counts = (self.num_particles, len(self._colliders))
        if counts == self._solver_checked:
            return
        self._solver_checked = counts
        self._limits = self.solver.time_step_limits(self._world)
        if not self._stepping.auto:  # ("auto" picks a dt within the limits, or warns that it cannot)
            for message in self.solver.check(self._world, self.dt):
                self._warn_once(message)
        self._watch_stability()

    def _place_out(self):
        """The solver moves particles placed inside colliders since it last looked out of them
        (Solver.place_out: the penalty solver's contacts would throw them out)."""
        store = self._particles
        if store.placed_from is not None and store.placements != self._placed_checked:
            self._placed_checked = store.placements
            self.solver.place_out(self._world, store.placed_from)

    def _warn_once(self, message: str):
        if message not in self._solver_warned:
            self._solver_warned.add(message)
            notices.warn(message, RuntimeWarning)

    def _watch_stability(self):
        """Watch the speeds while dt is beyond the stability limit of the solver's stiffest
        explicit contact (the run may diverge: _check_health stops it)."""
        limits = self._limits
        if limits is None or self.dt <= limits[1]:
            self._watch = None
        elif self._watch is None:
            self._watch = (self._particles.max_speed(), self.time)

    def _choose_substeps(self):
        """substeps="auto": this frame's substeps (SubstepChoice.choose), dt and what set it."""
        limits = self._limits
        speed = self._particles.max_speed() if self.num_particles else 0.0
        speed = max([speed, self._bodies.max_speed()]
                    + [float(np.linalg.norm(e.velocity)) for e in self._emitters if not e.finished(self.time)])
        n, limit = self._stepping.choose(None if limits is None else limits[0], speed,
                                         self._particles.min_radius, float(np.linalg.norm(self.gravity)))
        if limit == "max_substeps":
            self._warn_once(f"substeps='auto': this scene needs more than max_substeps = {self._stepping.max_substeps}"
                            f" substeps a frame at times: frames then take max_substeps substeps of "
                            f"{self._stepping.frame_dt / n:.3g} s, beyond the scene's limits (see stats()). Raise "
                            "max_substeps")
        dt = self._stepping.frame_dt / n
        if dt != self.dt:
            self._time_base, self._substep_count, self.dt = self.time, 0, dt
            self._watch_stability()
        self.substeps, self._substep_limit = n, limit

    def _check_health(self):
        if self._bodies.count:
            self._check_bodies()
        fresh = self._particles.collect_stats()
        totals = self._particles.totals
        if self._watch is not None:
            self._check_divergence()
        if fresh["non_finite"]:
            bad = np.flatnonzero(self.particle_status() == "non_finite")
            advice = self.solver.stability_advice(self._world)
            raise SimulationError(
                f"{fresh['non_finite']} particle(s) turned NaN or inf and were frozen at their last finite "
                f"state (indices {bad[:10].tolist()}{' ...' if bad.size > 10 else ''}) at t = {self.time:.6g} s. "
                f"Check their velocities and the colliders' motion; a smaller dt (now {self.dt:g} s) may help"
                + (f": {advice}." if advice else "."))
        if self._pairs is not None and not self._warned_dropped:
            dropped = self._pairs.neighbour_overflow
            if dropped:
                self._warned_dropped = True
                notices.warn(
                    f"neighbour lists were full by t = {self.time:.6g} s: {dropped} neighbour(s) of particles with "
                    f"more than {NEIGHBOUR_CAPACITY} others within reach were left out, and contacts with them "
                    "missed (the running count: neighbour_overflow of what enable_particle_collisions returned). "
                    "The lists reach r_i + r_j + a margin (contact_margin, or a quarter of the smaller radius) "
                    "and verlet_skin: smaller ones, or a pile less crushed, keep them short", RuntimeWarning)
        if (self._pairs is not None and self.solver.pair_model == "dem" and not self._warned_crushed
                and not self._pairs.placing):
            self._check_crushed()
        if fresh["left_domain"]:
            notices.warn(f"{fresh['left_domain']} particle(s) left the domain by t = {self.time:.6g} s and were "
                          f"frozen ({totals['left_domain']} in all); see Scene.particle_status()", RuntimeWarning)

    def _check_bodies(self):
        """A body whose state turned NaN or inf stops the run (SimulationError): unlike a
        particle it cannot be frozen alone, since particles and other bodies touch it."""
        store = self._bodies.store
        bad = [b for b in range(store.count)
               if not (np.all(np.isfinite(store.x[b])) and np.all(np.isfinite(store.v[b]))
                       and np.all(np.isfinite(store.L[b])) and np.all(np.isfinite(store.R[b])))]
        if bad:
            raise SimulationError(
                f"body {bad[0]} ({type(store.entries[bad[0]].shape).__name__}) turned NaN or inf at "
                f"t = {self.time:.6g} s{' (and ' + str(len(bad) - 1) + ' more)' if len(bad) > 1 else ''}. "
                f"Check its mass and inertia against the particles' and its velocities; a smaller dt "
                f"(now {self.dt:g} s) may help.")

    def _check_crushed(self):
        """DEM pairs: warn once when particles overlap by more than CRUSHED_OVERLAP of the
        smaller radius, contacts too soft for the load they carry (a spring holds a load at
        overlap = load / k; docs/physics.md 5.4)."""
        deepest = self._pairs.overlap(self._world)["max"]
        if deepest > CRUSHED_OVERLAP:
            self._warned_crushed = True
            notices.warn(
                f"particles overlap by up to {100 * deepest:.0f} % of the smaller radius at t = {self.time:.6g} s: "
                "the DEM contacts are too soft for the load they carry (a spring holds a load at overlap = load / "
                "k; with hertz=, each contact's stiffness follows the masses of its particles, so a light particle "
                "cannot hold up a heavy one), or more particles are crowded together than the space holds. Give "
                "PenaltySolver(stiffness=...) in N/m for the heaviest load, with substeps='auto', or use the impulse "
                "solver, whose shock propagation keeps piles of any mass ratio apart", RuntimeWarning)

    def _check_divergence(self):
        """dt is beyond the stability limit (see _watch_stability): stop a run whose particles
        go faster than the speeds they had and gravity's could ever explain (explicit
        integration past its limit feeds energy into every stiff contact, growing
        geometrically), with the error that names the dt to use."""
        start_speed, since = self._watch
        plausible = start_speed + float(np.linalg.norm(self.gravity)) * (self.time - since)
        speed = self._particles.max_speed()
        if speed > DIVERGED_FACTOR * plausible + DIVERGED_SPEED:
            recommended, limit = self._limits
            raise SimulationError(
                f"the run is diverging: a particle moves at {speed:.3g} m/s at t = {self.time:.6g} s, where the "
                f"starting speeds and gravity explain at most {plausible:.3g} m/s, because dt = {self.dt:.3g} s is "
                f"beyond the stability limit {limit:.3g} s of the stiffest contact. Use dt <= {recommended:.3g} s "
                "(or substeps='auto'), or a softer contact")

    # ---------------------------------------------------------------- reading
    @property
    def gravity(self) -> np.ndarray:
        """Acceleration of every particle, m/s^2."""
        return self._world.gravity

    @gravity.setter
    def gravity(self, value):
        self._world = dataclasses.replace(self._world, gravity=validate.vector3("gravity", value))
        self._particles.wake_all()  # (what held a sleeping particle may no longer: docs/physics.md 5.3.1)

    @property
    def domain(self) -> tuple | None:
        """The domain box ((lower corner), (upper corner)) in m, or None."""
        return self._world.domain

    @property
    def time(self) -> float:
        """Seconds simulated."""
        return self._time_base + self._substep_count * self.dt

    @property
    def frame_time(self) -> float:
        """Seconds per frame: substeps * dt (frame_dt with substeps="auto")."""
        return self._stepping.frame_dt if self._stepping.auto else self.substeps * self.dt

    @property
    def num_particles(self) -> int:
        return self._particles.count

    @property
    def colliders(self) -> list[ColliderEntry]:
        return list(self._colliders.entries)

    @property
    def frame(self) -> int:
        """Frames stepped since the scene was built (or in the run a loaded state came from)."""
        return self._frame

    def ids(self) -> np.ndarray:
        """(N,) int64: each particle's id, unique and never reused, ascending; every reader
        (positions(), velocities(), ...) returns particles in this order, which is the order
        they were added in."""
        return self._particles.public_ids()

    def positions(self) -> np.ndarray:
        """(N, 3) copy of the particle centers, in the order they were added."""
        return self._particles.read("x")

    def velocities(self) -> np.ndarray:
        return self._particles.read("v")

    def angular_velocities(self) -> np.ndarray:
        """(N, 3) angular velocities in rad/s, in the order the particles were added: zero unless
        the solver spins particles (tc.PenaltySolver(spin=True))."""
        if self._particles.w is None:
            return np.zeros((self.num_particles, 3), dtype=runtime.float_dtype())
        return self._particles.read("w")

    def masses(self) -> np.ndarray:
        return self._particles.read("mass")

    def radii(self) -> np.ndarray:
        return self._particles.read("radius")

    def particle_status(self) -> np.ndarray:
        """Per particle, in the order they were added: "active", "left_domain" (left the
        domain box, frozen where it left) or "non_finite" (its state turned NaN/inf, frozen at
        its last finite state)."""
        return np.array(STATUS_NAMES)[self._particles.read("flags")]

    def sleeping(self) -> np.ndarray:
        """Per particle, in the order they were added: whether it is asleep (at rest in a pile,
        not moving until something wakes it; docs/physics.md 5.3.1)."""
        return self._particles.read("rest") < 0.0

    def status(self) -> np.ndarray:
        """The old name of particle_status() (removed in tai_coll 0.3)."""
        notices.warn("Scene.status() is now called particle_status(); the old name will be removed in tai_coll 0.3",
                      DeprecationWarning)
        return self.particle_status()

    def stats(self) -> dict:
        """Counts of events since the scene was built (failsafe and repulsion events, particles
        frozen: non_finite, left_domain), then the latest frame's substeps, its dt (s) and
        what chose them (substep_limit): "fixed" (the scene's substeps and dt), or with
        substeps="auto" "stability" (the stiffest contact), "cfl" (the travel limit),
        "frame_dt" (one substep, or dt's cap), "max_substeps" (capped). With rigid bodies:
        body_contacts (the bodies' contacts with colliders and each other found in the last
        substep, speculative ones included) and held_contacts (with particles held by their
        supports, docs/physics.md 7.2). With emitters or sinks: emitted, emission_skipped
        (owed particles that found no room) and removed (by sinks)."""
        out = dict(self._particles.totals, substeps=self.substeps, dt=self.dt, substep_limit=self._substep_limit)
        if self._emitters or len(self._sinks):
            out.update(emitted=sum(e.emitted for e in self._emitters),
                       emission_skipped=sum(e.skipped for e in self._emitters), removed=self._sinks.removed)
        if self._bodies.count:
            out.update(body_contacts=self._bodies.contacts, held_contacts=self._bodies.held)
        return out

    def set_velocities(self, velocities) -> None:
        v = validate.points("velocities", velocities)
        if v.shape != (self.num_particles, 3):
            raise ValueError(f"velocities must have shape ({self.num_particles}, 3); got {v.shape}")
        self._particles.write("v", v)

    def set_angular_velocities(self, angular_velocities) -> None:
        """Set every particle's angular velocity (rad/s); the solver must spin particles
        (tc.PenaltySolver(spin=True))."""
        w = validate.points("angular_velocities", angular_velocities)
        if w.shape != (self.num_particles, 3):
            raise ValueError(f"angular_velocities must have shape ({self.num_particles}, 3); got {w.shape}")
        if not self.solver.spin:
            raise ValueError(f"angular_velocities: the scene's solver does not spin particles ({self.solver!r}); "
                             "use tc.PenaltySolver(..., spin=True)")
        self._particles.enable_spin()
        self._particles.write("w", w)

    def set_positions(self, positions) -> None:
        x = validate.points("positions", positions)
        if x.shape != (self.num_particles, 3):
            raise ValueError(f"positions must have shape ({self.num_particles}, 3); got {x.shape}")
        self._particles.write("x", x)

    # ---------------------------------------------------------------- files
    def frame_data(self) -> export.Frame:
        """The particles now (positions, velocities, radii, masses, ids), time, frame number,
        frames per second and the bodies' poses, as exporters take them (tai_coll.export.Frame;
        tc.UsdRecorder.add)."""
        return checkpoint.frame_data(self)

    def save_frame(self, path) -> None:
        """Write the particles now (and the bodies' poses) to `path`, by its extension:
        .ply (binary; x, y, z, vx, vy, vz, radius, id per vertex), .npz (positions,
        velocities, radii, masses, ids, time, frame; body_... with bodies) or .usd/.usda/.usdc
        (one time sample at this frame; usd-core, the `usd` extra). For a USD animation of
        many frames, tc.UsdRecorder. Parent folders are made; files are written atomically."""
        export.format_of(path)  # (refuses a bad path before reading anything)
        export.save_frame(path, checkpoint.frame_data(self))

    def save_state(self, path):
        """Write everything the next step reads (particles with ids, spins, springs and
        flags, time, frame count, colliders' poses, bodies, emitters' random state, sinks'
        count, the pair solver's neighbour data) to `path`, a versioned .npz written
        atomically. Returns the path."""
        return checkpoint.save_state(self, path)

    def load_state(self, path) -> None:
        """Continue from a state save_state wrote. The scene must be built as the one that
        saved it (same colliders, bodies, emitters, sinks, solver and settings; its
        particles are replaced): else ValueError saying what differs. On the CPU the run then
        continues bit for bit as the saved one would have. FileNotFoundError if there is no
        such file."""
        checkpoint.load_state(self, path)

    def __repr__(self):
        bodies = f"{self._bodies.count} bodies, " if self._bodies.count else ""
        return (f"Scene({self.num_particles} particles, {bodies}{len(self._colliders)} colliders, dt={self.dt:g}, "
                f"substeps={self.substeps}, solver={self.solver!r}, t={self.time:.4g} s)")
