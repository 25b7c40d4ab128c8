"""The particle store: one array per quantity (structure of arrays), with a capacity that
grows by doubling. Order is the order of `add` and never changes."""

from __future__ import annotations

import numpy as np
import taichi as ti


ACTIVE = 0
LEFT_DOMAIN = 1  # left the scene's domain box: frozen where it left, no longer simulated
NON_FINITE = 2   # its state turned NaN/inf: frozen at its last finite state

# Slots of the per-scene event counters.
STAT_FAILSAFE = 0
STAT_REPULSION = 1
STAT_NON_FINITE = 2
STAT_LEFT_DOMAIN = 3
STAT_NAMES = ("failsafe", "repulsion", "non_finite", "left_domain")

QUANTITIES = ("x", "v", "mass", "radius", "flags")


class ParticleStore:
    """Positions x (m), velocities v (m/s), mass (kg), radius (m) and a status flag."""

    def __init__(self, capacity: int = 1024):
        self.count = 0
        self.capacity = 0
        self.max_radius = 0.0  # kept on the host: the hash grid's cell size needs it every substep
        # Kernels count events in a small i32 array; `collect_stats` drains it into Python
        # integers after every frame, so long runs of many particles cannot overflow it.
        self.stats = ti.ndarray(ti.i32, shape=len(STAT_NAMES))
        self.stats.fill(0)
        self.totals = dict.fromkeys(STAT_NAMES, 0)
        # `version` counts the times the state may have changed outside the impulse solver's
        # step kernel; the impulse solver keeps each particle's clearance (how far it can move
        # before it could touch a collider) between launches and trusts it only while
        # `clearance_key` (versions of store and collider table at its last launch) holds.
        self.version = 0
        self.clearance_key = None
        self._allocate(max(int(capacity), 1))

    def _allocate(self, capacity: int):
        old = {name: self.read(name) for name in QUANTITIES} if self.count else None
        self.x = ti.Vector.ndarray(3, float, shape=capacity)
        self.v = ti.Vector.ndarray(3, float, shape=capacity)
        self.mass = ti.ndarray(float, shape=capacity)
        self.radius = ti.ndarray(float, shape=capacity)
        self.flags = ti.ndarray(ti.i32, shape=capacity)
        self.clearance = ti.ndarray(float, shape=capacity)
        self.capacity = capacity
        self.version += 1
        if old is not None:
            for name, values in old.items():
                self._write_range(name, 0, values)

    def _write_range(self, name: str, start: int, values: np.ndarray):
        self.version += 1
        array = getattr(self, name)
        full = array.to_numpy()
        full[start:start + len(values)] = values
        array.from_numpy(np.ascontiguousarray(full, dtype=full.dtype))

    def add(self, x, v, mass, radius) -> slice:
        """Append validated host arrays; returns the slice of the new particles."""
        n = len(x)
        if self.count + n > self.capacity:
            self._allocate(max(2 * self.capacity, self.count + n))
        start = self.count
        for name, values in (("x", x), ("v", v), ("mass", mass), ("radius", radius),
                             ("flags", np.zeros(n, dtype=np.int32))):
            self._write_range(name, start, values)
        self.count += n
        if n:
            self.max_radius = max(self.max_radius, float(np.max(radius)))
        return slice(start, start + n)

    def clearances_hold(self, table) -> bool:
        """Whether the kept clearances still describe the particles against the collider
        `table`: nothing moved the particles or changed the table since they were written."""
        return self.clearance_key == (self.version, table.version)

    def clearances_written(self, table):
        """A kernel has just written the clearances for the particles as it left them."""
        self.clearance_key = (self.version, table.version)

    def read(self, name: str) -> np.ndarray:
        return getattr(self, name).to_numpy()[: self.count].copy()

    def write(self, name: str, values: np.ndarray):
        self._write_range(name, 0, values)

    def kernel_args(self, moves: bool = True):
        """The arrays in the order `ParticleArrays` takes them. A kernel given them may move
        the particles (unless the caller says `moves=False`), so the impulse solver's stored
        clearances stop counting."""
        if moves:
            self.version += 1
        return self.x, self.v, self.mass, self.radius, self.flags, self.stats

    def collect_stats(self) -> dict:
        """Move the kernels' event counts into `totals`; returns the counts just collected."""
        fresh = dict(zip(STAT_NAMES, (int(s) for s in self.stats.to_numpy())))
        if any(fresh.values()):
            self.stats.fill(0)
            for name, count in fresh.items():
                self.totals[name] += count
        return fresh
