"""Particles hitting particles (docs/physics.md 5): the orchestrator of a substep with pairs.

A substep with impulse pairs (the ImpulseSolver's, `impulse_substep`), in phases:
1. predict: candidates x1 = x + dt v1, v1 = v + dt g (symplectic Euler; predict.py);
2. neighbours: lists of particles within reach at the candidates (the hash grid);
3. elastic pass: for pairs overlapping at the candidates, the law with restitution on the
   velocities at the start of the substep, its change added to the candidates; then the
   colliders' own scheme on the candidates;
4. contact passes (e = 0, friction as usual) on the candidate velocities, re-integrating
   x1 = x + dt v1 after each, alternating with the colliders' contact passes, so that support
   from a floor reaches the top of a stack within a substep;
5. projection passes: overlap left after the velocity passes is removed by moving positions
   apart, split by inverse mass (momentum and the centre of mass unchanged), the velocity
   following for overlap that developed during the substep; overlap that was there at its
   start while the pair has an overlap allowance (placed overlapping: placement.py) goes by the
   candidates' positions only, at most max_push_speed * dt a substep; Gauss-Seidel
   then takes a settle pass: the law (with restitution: a pair that comes into contact just
   then still bounces) on the pairs touching at the final positions, positions unchanged,
   so no contact carries approaching velocity into the next substep; where masses differ
   widely, shock propagation first (shock.py): the colliders' contact passes, support
   levels, and projection passes (and the settle pass) with each pair's lower particle fixed;
6. colliders: the solver resolves the candidates against the colliders last, so no particle
   ends inside a collider; the result is the new state.
The passes visit the pairs one after another over a colouring of the grid (gauss_seidel.py,
the default) or all at once (jacobi.py). A substep after which every particle sleeps, none
woken since, is skipped: it would change nothing (sleeping.all_asleep). After calm substeps,
the lists leave out pairs of sleeping particles with nothing awake near, and a substep whose
passes wake a particle is run again with whole lists (awake_lists.py).
A substep with DEM pairs (the PenaltySolver's, `dem_substep`, in dem_substep.py): the pair forces at the start
(dem.py), then the solver's substep against the colliders with them as loads; while overlap
particles were placed with is left, a separation by positions after it (placement.separate).
Both reorder the particle store by cell now and then (`reorder`). The settings are a
PairSettings (settings.py); this object holds the work arrays, the grid, the lists and the
springs, and counts what happened.
"""

import math

import numpy as np

import taichi as ti

from ... import runtime
from ...neighbors.hash_grid import HashGrid
from ...neighbors.verlet import VerletLists
from ...response.laws import WET_LAWS
from ...types import host_vector, unused
from . import awake_lists, gauss_seidel, jacobi, shock
from .dem_substep import DemSubsteps
from .overlap import overlap

#: A body resting on particles held by their supports stops on them (docs/physics.md 7.2) where it meets
#: them slower than this many times |g| dt (a resting contact closes at |g| dt a substep); faster, they share it.
HELD_SPEED = 4.0
from .placement import SHRINK, PushCap, cap_push_velocity, grant_allowances, shrink_allowances
from .predict import predict_kernel
from .sleeping import all_asleep, update_rest, wake_key
from .settings import PairSettings
from .springs import SpringHistory

# Builds of the lists between reorderings of the store by cell (particles move little meanwhile: it stays coherent).
REORDER_INTERVAL = 8
# Radius ratio (largest / smallest) beyond which each pair is listed by its smaller particle.
BY_RADIUS_RATIO = 2.0


def reads_pass_flags() -> bool:
    """Whether the impulse passes read back if they changed anything and stop early: on the
    CPU, where a read is cheap; not on a GPU (ParticleCollisions._passed)."""
    return runtime.info().arch == "cpu"


@runtime.bound_to_runtime
class ParticleCollisions(DemSubsteps):
    """Particle-particle collisions of a scene (Scene.enable_particle_collisions returns it).
    Its arrays belong to the Taichi runtime it was built in: after tc.init restarts Taichi,
    its methods and counters raise a clear RuntimeError (runtime.bound_to_runtime).

    settings: the PairSettings (its fields also read through this object: .method,
        .iterations, ...).
    neighbour_overflow, history_overflow, list_builds: what happened so far (see each).
    """

    def __init__(self, settings: PairSettings):
        self._runtime = runtime.ensure_init()
        self.settings = settings
        self.grid = HashGrid()
        self.lists = VerletLists()
        self.springs = SpringHistory()
        self.capacity = 0
        self._since_reorder = REORDER_INTERVAL  # lists built since the store was last reordered
        self._sorted_key = None  # the store's (edits, count) when the grid last sorted it
        self._latest_counts = None  # the array with the latest per-particle contact counts (Jacobi)
        self._pairs = True  # whether this substep's lists hold any pair (see impulse_substep)
        self._dem_dropped = 0  # neighbours the DEM lists left out (the grid's queries found them)
        self._law = None  # (key, the DEM law's argument pack)
        self._allowance_left = 0.0  # an upper bound of every particle's overlap allowance (m)
        self._allowance_ceiling = 0.0  # DEM pairs: the most allowance any particle may have (m)
        self._sleep = False  # whether particles may sleep this substep (the passes then take sleep=True)
        self._table_seen = None  # the collider table's version at the last substep (see _may_sleep)
        self._pushing = True  # whether the last resort may push particles out of colliders (see impulse_substep)
        self.levels = None  # support levels of shock propagation (shock.py), allocated when first needed
        self._push_cap = None  # placement.PushCap: its work while allowances are left
        self._awake, self._slept = ti.ndarray(ti.i32, shape=1), None  # update_rest's (see all_asleep)
        self._calm, self.redo = None, None  # lists of the awake (see impulse_substep; made at its first substep)
        self._asleep = ti.ndarray(ti.i32, shape=1)  # update_rest's: whether any particle slept
        self._asleep.fill(0)

    def __getattr__(self, name):
        # the settings' fields, read through this object as before it had `settings`
        if name in PairSettings.__dataclass_fields__:
            return getattr(self.settings, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __repr__(self):
        return f"ParticleCollisions({self.settings})"

    def _ensure(self, capacity: int):
        """Work arrays as large as the particle store (so whole-array copies line up)."""
        if capacity == self.capacity:
            return
        self.capacity = capacity
        self.x1 = ti.Vector.ndarray(3, float, shape=capacity)
        self.v1 = ti.Vector.ndarray(3, float, shape=capacity)
        self.v_start = ti.Vector.ndarray(3, float, shape=capacity)
        self.delta = ti.Vector.ndarray(3, float, shape=capacity)
        self.contacts = ti.ndarray(ti.i32, shape=capacity)
        self.torque = None  # DEM pairs of spinning particles (see _loads)
        self._load_args = None
        self.changed = ti.ndarray(ti.i32, shape=1)
        self.levels = self._push_cap = None
        self._largest = ti.ndarray(float, shape=1)
        self.lists.invalidate()

    # ---------------------------------------------------------------- counters
    @property
    def list_builds(self) -> int:
        """Substeps that built the neighbour lists (the others reused them, or every particle slept)."""
        return self.lists.builds

    @property
    def neighbour_overflow(self) -> int:
        """Neighbours left out of full lists since the start, and contacts with them missed (a
        read from the device); more than NEIGHBOUR_CAPACITY particles within a particle's reach
        means particles far smaller than the largest, or a pile crushed far beyond its radii.
        (The DEM kernel's lists miss none: while they are full it queries the grid instead.)"""
        runtime.check_generation(self._runtime.generation, "this ParticleCollisions")
        return self.grid.dropped() - self._dem_dropped

    @property
    def history_overflow(self) -> int:
        """Contacts a particle touched beyond the HISTORY whose tangential springs it keeps, summed
        over the substeps so far (a read from the device): these slid by the regularised
        friction instead."""
        runtime.check_generation(self._runtime.generation, "this ParticleCollisions")
        return self.springs.overflowed

    @property
    def forward_lists(self) -> bool:
        """Whether the neighbour lists hold each pair once (HashGrid.build's forward lists):
        what the Gauss-Seidel passes read; Jacobi's read every particle's full list."""
        return self.settings.method == "gauss-seidel"

    def arrays(self) -> list:
        """Every per-particle array held here and in the grid (for memory accounting): the
        work arrays (those of the impulse passes only when they ran), Verlet, springs, torques."""
        if not self.capacity:
            return []
        held = [self.delta] + self.grid.arrays() + self.springs.arrays()
        if self._latest_counts is not None:
            held += [self.x1, self.v1, self.v_start, self.contacts]
        if self.lists.listed_at is not None:
            held.append(self.lists.listed_at)
        if self.torque is not None:
            held.append(self.torque)
        held += [self.levels] if self.levels is not None else []
        held += self._push_cap.arrays() if self._push_cap is not None else []
        return held

    # ---------------------------------------------------------------- the grid and the store's order
    def _sort(self, particles, x, cell_size: float):
        """The grid's counting sort of the store's particles (at positions x)."""
        self.grid.sort(x, particles.radius, particles.flags, particles.count, cell_size)
        self._sorted_key = (particles.edits, particles.count)

    def _reorder(self, particles):
        """Put the store in the order of the grid's last sort, if it sorted the store as it is
        (the particles have moved since, by a substep or a few: the order stays coherent),
        at most once every REORDER_INTERVAL calls."""
        self._since_reorder += 1
        if (self.settings.reorder and particles.count and self._since_reorder >= REORDER_INTERVAL
                and self._sorted_key == (particles.edits, particles.count)):
            particles.permute(self.grid.entries, particles.count)
            self.springs.permute(self.grid.entries, particles.count, particles)  # springs move with them
            self._since_reorder = 0

    def compacted(self, order, n: int, particles):
        """The store removed particles (ParticleStore.compact: slot k holds what slot order[k]
        held): the springs move with the particles left; what else is kept per slot is keyed
        by the store's edits and rebuilt."""
        self.springs.permute(order, n, particles)

    # ---------------------------------------------------------------- impulse pairs
    def impulse_substep(self, world, solver, dt: float):
        """One substep with impulse pairs (the module's phases 1-6); solver: the scene's
        ImpulseSolver, which resolves the colliders."""
        particles = world.particles
        self._ensure(particles.capacity)
        settings = self.settings
        r_max = particles.max_radius
        m = settings.material
        law = dict(restitution=m.restitution, friction=m.friction, wet_friction=m.wet_friction,
                   wet_law=WET_LAWS["linear"])
        placed = self._place(particles)
        sleep = self._may_sleep(world)
        table = world.colliders
        support = settings.method == "gauss-seidel" and any(world.gravity) and table.has_bodies
        # (the substep's wakes are read: the all-asleep skip and the lists of the awake may apply)
        watched = sleep and not (placed or self._pushing or (world.bodies is not None and world.bodies.open)) and \
            settings.method == "gauss-seidel" and reads_pass_flags()
        if watched and all_asleep(self._awake, self._slept, wake_key(particles, table)):
            return  # every particle sleeps and none was woken: the substep would change nothing (all_asleep)
        # lists of the awake (awake_lists.py) after calm substeps, from the rest times update_rest left,
        # some asleep
        self._calm = self._calm or awake_lists.Calm()  # (a loaded state counts anew: the same results)
        awake_only = self._calm.wanted(watched and not (support or shock.needed(world)) and
                                       settings.skin_length(r_max) == 0.0 and self._slept == wake_key(particles, table)
                                       and runtime.read_small(self._asleep, 1)[0] != 0)
        # 1. predict; 2. neighbours of the candidates (Jacobi: and their contact counts, which
        #    the first pass's shares use; each pass counts them for the next, into the other array)
        #    (and v(t) into v_start, x(t) into delta while particles may sleep: see 3.)
        contacts = self._predict_and_list(world, dt, settings.margin_terms(), settings.skin_length(r_max), sleep,
                                          awake_only)
        placed = self._pair_phases(world, solver, dt, law, contacts, placed, sleep, support)
        if watched and self._calm.woke(self._pairs, self.capacity, awake_only) and awake_only:
            # a pass woke a particle, whose pairs with sleeping ones the lists may lack: again, whole
            placed = self._pair_phases(world, solver, dt, law, awake_lists.again(self, particles), placed, sleep,
                                       support)
        # 6. colliders last, and the new state. With rigid bodies, their substep ends first:
        #    the particles are then kept out of them at the poses they were committed to, not
        #    the predicted ones (docs/physics.md 7.2)
        bodies = world.bodies if world.bodies is not None and world.bodies.open else None
        solver.resolve_candidates(world, dt, self.x1, self.v1, contact_only=True, store_state=bodies is None)
        if bodies is not None:
            bodies.end(world, dt, in_table=True)
            allow = math.isfinite(settings.max_push_speed)
            pushed = solver.store_out_of_bodies(world, self.x1, self.v1, allow)
            if pushed > 0.0:
                bodies.take_pushes(world)
                if allow:
                    self._allowance_left = max(self._allowance_left, pushed)
        if support:
            table.set_support(None, None)
        self._latest_counts = self._counts[0]
        self._relax(particles, dt)
        if sleep:  # rest times, particles falling asleep (v_start: v(t), as the elastic pass left it)
            update_rest(particles.args, self.delta, self.v_start, host_vector(world.gravity), dt,
                        settings.sleep_time, settings.sleep_drift, self._awake, self._asleep)
            self._slept = wake_key(particles, world.colliders)

    def _pair_phases(self, world, solver, dt: float, law: dict, contacts, placed: bool, sleep: bool,
                     support: bool) -> bool:
        """impulse_substep's phases 3 to 5 (contacts: the array of contact counts at the
        candidates); returns whether placed overlap is being removed."""
        particles, settings, table = world.particles, self.settings, world.colliders
        # Gauss-Seidel passes over lists that hold no pair would change nothing: where the
        # flags are read (the CPU), the passes are skipped then (a lone particle, a sparse rain)
        self._pairs = settings.method != "gauss-seidel" or not reads_pass_flags() or self.grid.listed_any()
        self._counts = [contacts, self.contacts if contacts is not self.contacts else self.grid.touching]
        # A body lying on particles held by what they rest on is stopped by them in this
        # substep's collider passes (shock propagation, docs/physics.md 7.2), where it meets
        # them slower than HELD_SPEED |g| dt.
        if support:
            g = float(np.linalg.norm(world.gravity))
            up = -np.asarray(world.gravity) / g
            table.set_support(self._support_levels(world, particles.x), up * HELD_SPEED * g * dt)
        # 3. elastic pass on v(t) (v_start, which the prediction wrote; delta holds x(t) for
        #    update_rest when particles may sleep: Gauss-Seidel leaves delta free)
        # the passes' wake thresholds (None: nobody sleeps): the elastic pass's, and the later
        # passes', whose velocities include this substep's gravity, which a sleeping particle's
        # lack (a particle resting on one closes in on it by |g| dt)
        wake_speeds = ((settings.wake_speed, settings.wake_speed + dt * math.hypot(*world.gravity)) if sleep
                       else (None, None))
        if not self._velocity_pass(particles, dt, law, elastic=True, wake_speed=wake_speeds[0]) and \
                settings.method == "jacobi":
            self._counts.reverse()  # (it counted the contacts all the same)
        #    ... and the colliders' own scheme on the candidates; its pushes out of colliders become
        #    overlap allowance (watched after placements and added colliders, until none: a read)
        pushing = self._pushing and math.isfinite(settings.max_push_speed)
        if pushing:
            self._largest.fill(0)
        solver.resolve_candidates(world, dt, self.x1, self.v1, store_state=False,
                                  pushed=self._largest if pushing else None)
        if pushing:
            pushed = float(self._largest[0])
            self._pushing = pushed > 0.0
            self._allowance_left += pushed  # (a particle's allowance grew by its push at most)
            placed = self.placing
        # 4. contact passes on the candidate velocities, e = 0, alternating with the colliders'
        #    contact passes. A pass that finds no approaching pair ends the loop (the next would
        #    be the same); likewise a projection pass that finds no overlap.
        contact_law = dict(law, restitution=0.0)
        for _ in range(settings.iterations):
            if not self._velocity_pass(particles, dt, contact_law, elastic=False, wake_speed=wake_speeds[1]):
                break
            solver.resolve_candidates(world, dt, self.x1, self.v1, contact_only=True, store_state=False)
        # 5. projection passes on positions (the first also takes up to max_push_speed * dt of the
        #    overlap there was at the start of the substep, by positions only)
        if placed:
            if self._push_cap is None:
                self._push_cap = PushCap(self.capacity)
            self._push_cap.entering(self.v1)
        for k in range(settings.projection_iterations):
            if not self._projection_pass(particles, dt, placed, settings.max_push_speed * dt if k == 0 else 0.0):
                break
        if placed:  # no more than max_push_speed from the separation of placed crowds, momentum kept
            cap_push_velocity(particles, self.grid.lists, self._push_cap, settings.max_push_speed, self.v1)
        if settings.method == "gauss-seidel":
            levels = self._shock(world, solver, dt, placed)
            # a last velocity pass at the final positions: without it, particles jammed deep in
            # a pile are thrown back and forth by the projection's velocity, towards a different
            # neighbour each substep (a jitter of period two substeps)
            if self._pairs:
                gauss_seidel.settle_pass(particles.args, self.grid.args, self.grid.lists, law, dt, self.changed,
                                         self.x1, self.v1, wake_speed=wake_speeds[1], levels=levels,
                                         rest_speed=world.rest_speed(dt))
        return placed

    def _support_levels(self, world, x):
        """The support levels (shock.py) at positions x, into self.levels."""
        if self.levels is None or self.levels.shape[0] < self.capacity:
            self.levels = ti.ndarray(ti.i32, shape=self.capacity)
        shock.support_levels(world, self.grid.lists, x, self.levels, self.changed)
        return self.levels

    def _shock(self, world, solver, dt: float, placed: bool):
        """Shock propagation (shock.py) where the particles' masses differ by more than
        SHOCK_MASS_RATIO under gravity: the colliders' contact passes (so that particles pushed
        into a floor are back on it), the support levels, and projection passes with each
        pair's lower particle fixed. Returns the levels for the settle pass (None without)."""
        particles = world.particles
        if not shock.needed(world):
            return None
        if self.levels is None:
            self.levels = ti.ndarray(ti.i32, shape=self.capacity)
        solver.resolve_candidates(world, dt, self.x1, self.v1, contact_only=True, store_state=False)
        shock.support_levels(world, self.grid.lists, self.x1, self.levels, self.changed)
        for _ in range(shock.SHOCK_PASSES):
            gauss_seidel.projection_pass(particles.args, self.grid.args, self.grid.lists, 1.0, dt, placed, 0.0,
                                         self.changed, self.x1, self.v1, sleep=self._sleep, levels=self.levels)
            if not self._changed():
                break
        return self.levels

    def _may_sleep(self, world) -> bool:
        """Whether particles may sleep this substep (sleeping.py): sleeping is on, gravity is
        not zero (without it nothing presses particles together, so nothing trembles, and a
        sleeping particle, immovable to the passes, would take momentum out of every slow
        exchange), and no collider is kinematic (its motion may take away a sleeping particle's
        support without touching it); otherwise every particle that may have slept is woken.
        So is every one when a collider was added (the still table's version changed), which may
        hold or push what sleeps (and sets self._pushing). Sets self._sleep."""
        table = world.colliders
        sleep = self.settings.sleep_time is not None and any(world.gravity) and not table.has_kinematic
        added = self._table_seen is not None and table.version != self._table_seen and not table.has_kinematic
        if self._sleep and (added or not sleep):
            world.particles.wake_all()
        self._sleep = sleep
        self._table_seen = table.version
        self._pushing = self._pushing or added
        return sleep

    def _predict_and_list(self, world, dt: float, margin: tuple, skin: float, sleep: bool, awake_only=False):
        """Phases 1 and 2: the candidates, and neighbour lists of pairs within r_i + r_j + margin
        (margin: (m, radii), settings.margin_terms) + skin of each other at them, kept from
        earlier substeps while they still hold; also v(t) into v_start and, if sleep, x(t) into
        delta (in the store's order after any reordering here). Returns the array holding each
        particle's contact count at the candidates (for the first pass). awake_only: lists of the
        awake (awake_lists.py; self.redo then holds what awake_lists.again needs)."""
        particles = world.particles
        n = particles.count
        length, radii = margin
        # lists owned by the smaller particle of each pair where radii differ widely (a large
        # particle among small ones would otherwise list hundreds); see HashGrid.build
        by_radius = particles.max_radius > BY_RADIUS_RATIO * particles.min_radius
        key = (particles.edits, n, margin, skin, particles.capacity, self.settings.method)
        keep = skin > 0.0
        if keep:
            self.lists.ensure(self.capacity)
        predict = predict_kernel(keep)
        launch = dict(particles=particles.args, gravity=host_vector(world.gravity), dt=dt,
                      seen=self.lists.args if keep else unused(), reach2=(0.5 * skin) ** 2, keep_x=int(sleep),
                      x1=self.x1, v1=self.v1, stale=self.changed, v_start=self.v_start, x_start=self.delta)
        if self.lists.key == key and keep:
            predict(**launch)
            if not self._changed():
                return self._latest_counts
        self._reorder(particles)  # (swaps the store's arrays)
        launch["particles"] = particles.args
        predict(**launch)
        listed = dict(flags=particles.flags, n=n, margin=length + skin, forward=self.forward_lists,
                      margin_radii=radii, by_radius=by_radius)
        self.redo = (predict, launch, listed, self.grid.dropped()) if awake_only else None
        self.grid.build(self.x1, particles.radius, cell_size=(2.0 + radii) * particles.max_radius + length + skin,
                        **listed, awake_only=particles.rest if awake_only else None)
        self._sorted_key = (particles.edits, n)
        if keep:
            self.lists.mark(self.x1, particles.flags, n)
        self.lists.built((particles.edits,) + key[1:])
        return self.grid.touching

    def _velocity_pass(self, particles, dt: float, law: dict, elastic: bool, wake_speed: float | None) -> bool:
        """One velocity pass (elastic: on v(t), else a contact pass on the candidates' velocities;
        wake_speed: m/s, see sleeping.wakes; None while nobody sleeps); returns whether any pair
        approached."""
        if not self._pairs:
            return False  # (no pair listed: see impulse_substep)
        v_test = self.v_start if elastic else self.v1  # the velocities the law acts on
        if self.settings.method == "gauss-seidel":
            # the elastic pass is not over-relaxed: an isolated pair bounces with e exactly
            gauss_seidel.velocity_pass(elastic, particles.args, self.grid.args, self.grid.lists, law,
                                       1.0 if elastic else self.settings.relaxation, dt, self.changed,
                                       v_test, self.x1, self.v1,
                                       wake_speed=wake_speed)
        else:
            jacobi.velocity_pass(particles=particles.args, lists=self.grid.lists, contacts=self._counts[0],
                                 v_test=v_test, **law, relaxation=self.settings.relaxation, dt=dt,
                                 elastic=int(elastic), dv=self.delta, contacts_now=self._counts[1],
                                 changed=self.changed, v_start=self.v_start, x1=self.x1, v1=self.v1)
        return self._passed()

    def _projection_pass(self, particles, dt: float, placed: bool, push_distance: float) -> bool:
        """One projection pass; placed: overlap allowances are left, and up to push_distance (m)
        of them goes by positions only. Returns whether any pair had overlap to remove."""
        if not self._pairs:
            return False  # (no pair listed: see impulse_substep)
        if self.settings.method == "gauss-seidel":
            gauss_seidel.projection_pass(particles.args, self.grid.args, self.grid.lists, self.settings.relaxation, dt,
                                         placed, push_distance, self.changed, self.x1, self.v1,
                                         sleep=self._sleep)
        else:
            # (v_start, the elastic pass's copy of v(t), is free once the velocity passes are done)
            jacobi.projection_pass(particles=particles.args, lists=self.grid.lists, contacts=self._counts[0],
                                   relaxation=self.settings.relaxation, dt=dt, placed=placed,
                                   push_distance=push_distance,
                                   dx=self.delta, dx_followed=self.v_start, contacts_now=self._counts[1],
                                   changed=self.changed, x1=self.x1, v1=self.v1)
        return self._passed()

    def _changed(self) -> bool:
        """Whether the last pass (or check of the lists) had anything to do (a read from the device)."""
        return bool(runtime.read_small(self.changed, 1)[0])

    def _passed(self) -> bool:
        """Whether the last pass had anything to do; a Jacobi pass that did passes its contact
        counts on to the next (see jacobi.pair_share). On a GPU the flag is not read and the passes run their
        full count: a read waits for every kernel launched before it, so the host could never launch ahead of the
        GPU (an H200, 1M-particle bed: Jacobi passes 80 ms a frame with the reads, 36 without; Gauss-Seidel 105
        and 79). A pass after one that found nothing to do finds nothing either, and leaves the state as it was."""
        changed = self._changed() if reads_pass_flags() else True
        if changed and self.settings.method == "jacobi":
            self._counts.reverse()
        return changed

    # ---------------------------------------------------------------- overlap particles were placed with
    def _place(self, particles) -> bool:
        """Give particles placed since the last substep (added, or moved by set_positions) their
        overlap allowances: overlap they were placed with is an error of position, removed at
        max_push_speed by positions only (impulse pairs: the projection passes; DEM pairs: the
        separation after the substep, the spring acting beyond the allowances), not a collision
        (docs/physics.md 5.2.1). Returns whether any allowance is left (the passes then take the
        placed particles' path)."""
        if particles.placed_from is not None and particles.count and math.isfinite(self.settings.max_push_speed):
            self._sort(particles, particles.x, 2.0 * particles.max_radius)
            self.lists.invalidate()  # the sort replaced the buckets the lists came from
            largest = grant_allowances(self.grid, particles.count, particles.placed_from, particles.allowance,
                                       self._largest)
            self._allowance_left = max(self._allowance_left, largest)
            self._allowance_ceiling = max(self._allowance_ceiling, largest)
            particles.placed_from = None
            self._pushing = True
        return self.placing

    @property
    def placing(self) -> bool:
        """Whether overlap particles were placed with is still being removed (allowances left)."""
        return self._allowance_left > 0.0

    def _relax(self, particles, dt: float):
        """Impulse pairs, at the end of a substep: every allowance shrinks by SHRINK *
        max_push_speed * dt (a pair's, the sum of its two, by twice that)."""
        if self._allowance_left > 0.0:
            amount = SHRINK * self.settings.max_push_speed * dt
            self._allowance_left = shrink_allowances(particles.count, amount, particles.allowance, self._largest)

    # ---------------------------------------------------------------- measuring
    def overlap(self, world) -> dict:
        """Overlap between particles now, relative to the smaller radius of each pair:
        {"max": ..., "mean": ... over overlapping pairs, "pairs": count}."""
        particles = world.particles
        self._sort(particles, particles.x, 2.0 * particles.max_radius)
        if self.grid.forward:
            # the sort replaced the buckets that forward lists (Gauss-Seidel's) are coloured by;
            # full lists (Jacobi's, DEM's) hold store indices only and stay valid, so measuring
            # (the scene's check of DEM overlap, every frame) neither costs a rebuild nor
            # changes the run
            self.lists.invalidate()
        self._ensure(particles.capacity)
        return overlap(self.grid, particles.flags, particles.count, self.delta)
