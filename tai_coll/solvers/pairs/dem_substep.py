"""ParticleCollisions' substep with DEM pairs (the PenaltySolver's; collisions.py has the impulse
pairs' and the work both share): the pair forces at the start of the substep (dem.py), the
solver's substep against the colliders with them as loads, then while overlap particles were
placed with is left the separation by positions (placement.separate), and where masses differ
widely the overlap limit of shock propagation (shock.py)."""

import taichi as ti

from ... import runtime
from ...types import unused
from ..penalty import Forces, ForcesAndTorques
from . import dem, shock
from .placement import DEM_CEILING, DEM_SHRINK, separate


class DemSubsteps:
    """The DEM half of ParticleCollisions (its base class): methods on its grid, lists, springs
    and work arrays."""

    def dem_substep(self, world, solver, dt: float):
        """One substep with DEM pairs: their forces at the substep's start, then the solver's
        substep (a PenaltySolver) against the colliders with those forces as loads, then while
        allowances are left the separation of placed overlap (`_separate`)."""
        particles = world.particles
        self._ensure(particles.capacity)
        settings = self.settings
        with_springs = settings.tangential_springs
        spinning = solver.spin
        if with_springs:
            self.springs.fit(particles, spinning)  # before the reordering, which moves them with the store
        if spinning:
            particles.enable_spin()  # (before the reordering, which moves the spins with the store)
        loads = self._loads(spinning)
        self._place(particles)
        skin = settings.skin_length(particles.max_radius)
        listed = skin > 0.0 and self._dem_lists(particles, skin)
        if not listed:
            if skin == 0.0:  # (with lists, the store is reordered when they are built)
                self._reorder(particles)
            self._sort(particles, particles.x, 2.0 * particles.max_radius)
        kernel = dem.dem_force_kernel(runtime.info().precision, listed, with_springs, spinning)
        kernel(particles=particles.args, candidates=self.grid.lists if listed else self.grid.args,
               inv_cell=self.grid.inv_cell, ids=particles.ids,
               springs=self.springs.args if with_springs else unused(),
               spin=particles.spin_args if spinning else unused(), law=self._dem_law(solver, dt), loads=loads)
        if with_springs:  # this substep's springs are the current ones
            self.springs.swap()
        solver.advance(world, dt, 1, loads=loads)
        if self.placing:
            self._separate(world, dt, listed)
        self._limit_dem_overlap(world, dt, listed)

    def _limit_dem_overlap(self, world, dt: float, listed: bool):
        """DEM pairs where masses differ by more than SHOCK_MASS_RATIO under gravity (shock.py):
        the support levels at the new positions, then Jacobi passes (shock.limit_passes) that
        remove overlap beyond DEM_OVERLAP_LIMIT of each pair's smaller radius, the lower level
        immovable, until none is left or SHOCK_PASSES (docs/physics.md 5.4). The pairs: the
        force kernel's lists, or (it queried the grid) full lists of the pairs touching now."""
        particles = world.particles
        if not shock.needed(world):
            return
        if self.levels is None:
            self.levels = ti.ndarray(ti.i32, shape=self.capacity)
        if not listed:
            dropped = self.grid.dropped()
            self.grid.build(particles.x, particles.radius, particles.flags, particles.count,
                            2.0 * particles.max_radius, 0.0)
            self._dem_dropped += self.grid.dropped() - dropped  # (its overflow is this pass's, not the forces')
            self.lists.invalidate()  # the Verlet lists, if any, were in the arrays just rebuilt
        shock.support_levels(world, self.grid.lists, particles.x, self.levels, self.changed)
        for _ in range(shock.SHOCK_PASSES // shock.PASSES_PER_LAUNCH):
            shock.limit_passes(particles.args, world.colliders.args, world.colliders.groups, self.grid.lists,
                               self.levels, shock.DEM_OVERLAP_LIMIT, self.contacts, self.delta, self.v1, self.changed)
            if not self._changed():
                break

    def _separate(self, world, dt: float, listed: bool):
        """DEM pairs, at the end of a substep while allowances are left (placement.separate):
        overlap particles were placed with goes by positions only, at most max_push_speed * dt
        a substep, and the allowances follow the overlap left; their ceiling comes down by
        DEM_CEILING of that a substep (docs/physics.md 5.2.1). The separation's candidates are
        the force kernel's (listed: the lists, else the grid sorted at the substep's start); its
        moves go to the loads' array (delta), free once the solver's substep has applied them,
        its changes of velocity to v1 (the impulse passes')."""
        push_distance = self.settings.max_push_speed * dt
        self._allowance_ceiling = max(self._allowance_ceiling - DEM_CEILING * push_distance, 0.0)
        candidates = self.grid.lists if listed else self.grid.args
        self._allowance_left = separate(world, candidates, self.grid.inv_cell, listed, push_distance,
                                        DEM_SHRINK * push_distance, self._allowance_ceiling, self.contacts,
                                        self.delta, self.v1, self._largest)

    def _loads(self, spinning: bool):
        """The pair forces (and torques, for spinning particles) as one argument pack."""
        if spinning and self.torque is None:
            self.torque = ti.Vector.ndarray(3, float, shape=self.capacity)
        if self._load_args is None or self._load_args[0] != spinning:
            pack = ForcesAndTorques(force=self.delta, torque=self.torque) if spinning else Forces(force=self.delta)
            self._load_args = (spinning, pack)
        return self._load_args[1]

    def _dem_law(self, solver, dt: float):
        """The DEM law's constants (dem.dem_law_type), rebuilt when dt or the solver's
        constants change."""
        m = self.settings.material
        constants = solver.contact_law()
        key = (dt, tuple(constants.values()), runtime.info().generation)
        if self._law is None or self._law[0] != key:
            pack = dem.dem_law_type(runtime.info().precision)(
                dt=dt, **constants, static_friction=m.static_friction, kinetic_friction=m.friction,
                viscous_friction=m.wet_friction, rolling_friction=m.rolling_friction,
                tangential_ratio=self.settings.tangential_ratio)
            self._law = (key, pack)
        return self._law[1]

    def _dem_lists(self, particles, skin: float) -> bool:
        """The DEM kernel's Verlet lists: every pair closer than r_i + r_j + skin, built from the
        grid (at most every REORDER_INTERVAL builds after reordering the store by it) and kept
        until some particle has moved more than skin / 2 from where they saw it, or changed
        status, or the store was written. Returns whether they hold every such pair: False
        when a particle had more neighbours than the lists keep (the force kernel then queries
        the grid, sorted anew, until the next build)."""
        n = particles.count
        key = (particles.edits, n, skin, particles.capacity, "dem")
        self.lists.ensure(self.capacity)
        if self.lists.key == key and not self.lists.moved(particles.x, particles.flags, n, skin):
            return self.lists.complete
        self._reorder(particles)  # (swaps the store's arrays)
        dropped = self.grid.dropped()
        self.grid.build(particles.x, particles.radius, particles.flags, n, 2.0 * particles.max_radius + skin, skin)
        self._sorted_key = (particles.edits, n)
        self.lists.mark(particles.x, particles.flags, n)
        self.lists.built((particles.edits,) + key[1:])
        self.lists.complete = self.grid.dropped() == dropped
        self._dem_dropped += self.grid.dropped() - dropped  # (not missed: see neighbour_overflow)
        return self.lists.complete

