"""The particle store: one array per quantity (structure of arrays), with a capacity that
grows by doubling, so adding particles (an emitter, every frame) reallocates only now and
then and never recompiles a kernel (array shapes are launch arguments).

Every particle has an id, given in the order of `add` and never reused (`ids`, one per
storage slot). The public order (what `read` returns and `write` takes) is ascending id,
which is the order particles were added in; the storage order may differ (`permute` puts
particles near each other in space next to each other in memory) and `compact` removes
particles (sinks) keeping the storage order of the rest. Kernels take the store's arrays as
one argument pack (`args`, types.ParticleArgs)."""


import numpy as np
import taichi as ti

from .. import runtime
from ..types import ACTIVE, STAT_NAMES, ParticleArgs, SpinArgs, new_ndarray

#: Ids are kept as int32 on the device (the DEM springs find their partners by id): a store
#: gives out at most this many in its life.
MAX_IDS = 2**31 - 1

QUANTITIES = ("x", "v", "mass", "radius", "flags", "allowance", "rest", "anchor")
#: A particle's kept separating plane (solvers/impulse.py): its direction (3), level, the
#: other colliders' clearance beyond the particle's kept clearance, and the collider's index.
SEPARATION_SIZE = 6
#: The most particles a scene holds. Taichi 1.7 computes an array's offsets in 32-bit integers, counting
#: the scalars of vector elements (its issue 6758: an element past 2**31 - 1 scalars is written at a
#: wrapped, negative offset; on the CPU a crash, elsewhere memory silently overwritten). The widest arrays
#: a particle has are its kept plane (SEPARATION_SIZE scalars) and the rigid bodies' ledger (two 3-vectors),
#: so 357,913,941 particles (particle collisions' neighbour lists allow fewer: hash_grid.MAX_LISTED).
MAX_STORED = (2**31 - 1) // SEPARATION_SIZE
#: Every array the store keeps per particle, in the order of _stored_arrays and _permute's arguments.
STORED = QUANTITIES + ("clearance", "separation", "ids")


@ti.kernel
def _permute(order: ti.types.ndarray(), n: ti.i32, x: ti.types.ndarray(), v: ti.types.ndarray(),
             mass: ti.types.ndarray(), radius: ti.types.ndarray(), flags: ti.types.ndarray(),
             allowance: ti.types.ndarray(), rest: ti.types.ndarray(), anchor: ti.types.ndarray(),
             clearance: ti.types.ndarray(), separation: ti.types.ndarray(), ids: ti.types.ndarray(),
             # outputs: slot k gets what slot order[k] held
             x2: ti.types.ndarray(), v2: ti.types.ndarray(), mass2: ti.types.ndarray(), radius2: ti.types.ndarray(),
             flags2: ti.types.ndarray(), allowance2: ti.types.ndarray(), rest2: ti.types.ndarray(),
             anchor2: ti.types.ndarray(), clearance2: ti.types.ndarray(), separation2: ti.types.ndarray(),
             ids2: ti.types.ndarray()):
    for k in range(n):
        i = order[k]
        x2[k] = x[i]
        v2[k] = v[i]
        mass2[k] = mass[i]
        radius2[k] = radius[i]
        flags2[k] = flags[i]
        allowance2[k] = allowance[i]
        rest2[k] = rest[i]
        anchor2[k] = anchor[i]
        clearance2[k] = clearance[i]
        separation2[k] = separation[i]
        ids2[k] = ids[i]


@ti.kernel
def _permute_spin(order: ti.types.ndarray(), n: ti.i32, w: ti.types.ndarray(),
                  # outputs: slot k gets the spin of slot order[k]
                  w2: ti.types.ndarray()):
    for k in range(n):
        w2[k] = w[order[k]]


@ti.kernel
def _append(x: ti.types.ndarray(), v: ti.types.ndarray(), mass: ti.types.ndarray(), radius: ti.types.ndarray(),
            flags: ti.types.ndarray(), allowance: ti.types.ndarray(), rest: ti.types.ndarray(),
            anchor: ti.types.ndarray(), ids: ti.types.ndarray(), start: ti.i32, first_id: ti.i32,
            new_x: ti.types.ndarray(), new_v: ti.types.ndarray(), new_mass: ti.types.ndarray(),
            new_radius: ti.types.ndarray()):
    """Slots start.. get the new particles: active, no allowance, awake, anchored where they are."""
    for k in range(new_x.shape[0]):
        i = start + k
        p = ti.Vector([new_x[k, 0], new_x[k, 1], new_x[k, 2]])
        x[i] = p
        v[i] = ti.Vector([new_v[k, 0], new_v[k, 1], new_v[k, 2]])
        mass[i] = new_mass[k]
        radius[i] = new_radius[k]
        flags[i] = ACTIVE
        allowance[i] = 0.0
        rest[i] = 0.0
        anchor[i] = p
        ids[i] = first_id + k


@ti.kernel
def _copy_into(target: ti.types.ndarray(), start: ti.i32, source: ti.types.ndarray()):
    for k in range(source.shape[0]):
        target[start + k] = source[k]


@ti.kernel
def _max_speed_sq(n: ti.i32, v: ti.types.ndarray(), flags: ti.types.ndarray(),
                  # outputs
                  largest: ti.types.ndarray()):
    for i in range(n):
        if flags[i] == ACTIVE:
            ti.atomic_max(largest[0], v[i].norm_sqr())


def _spin_array(capacity: int):
    """Angular velocities (rad/s) of `capacity` particles, all zero."""
    w = ti.Vector.ndarray(3, float, shape=capacity)
    w.fill(0.0)
    return w


def _numpy_dtype(array):
    """The numpy dtype of a Taichi ndarray's elements."""
    return {ti.f32: np.float32, ti.f64: np.float64, ti.i32: np.int32, ti.i64: np.int64}[array.dtype]


def _stored_arrays(capacity: int) -> tuple:
    """A fresh set of the STORED arrays."""
    return (ti.Vector.ndarray(3, float, shape=capacity), ti.Vector.ndarray(3, float, shape=capacity),
            ti.ndarray(float, shape=capacity), ti.ndarray(float, shape=capacity), ti.ndarray(ti.i32, shape=capacity),
            ti.ndarray(float, shape=capacity), ti.ndarray(float, shape=capacity),
            ti.Vector.ndarray(3, float, shape=capacity), ti.ndarray(float, shape=capacity),
            ti.Vector.ndarray(SEPARATION_SIZE, float, shape=capacity), ti.ndarray(ti.i32, shape=capacity))


class ParticleStore:
    """Positions x (m), velocities v (m/s), mass (kg), radius (m), a status flag, an overlap
    allowance (m: overlap with its neighbours that a particle was given when it was placed,
    removed by positions at a capped speed, docs/physics.md 5), a rest time (s: how long the
    particle has stayed near its anchor, the position where it came to rest, held by its
    contacts; negative: asleep, docs/physics.md 5.3.1);
    angular velocities w (rad/s) once a solver that spins particles asks for them
    (enable_spin)."""

    def __init__(self, capacity: int = 1024):
        self.count = 0
        self.capacity = 0
        self.max_count = MAX_STORED  # the most particles the store may hold (fewer with particle collisions)
        self.max_radius = 0.0  # kept on the host: the hash grid's cell size needs it every substep
        self.min_radius = float("inf")  # (Scene's substeps="auto" needs it every frame)
        self.mass_range = (float("inf"), 0.0)  # lightest and heaviest mass (the pair solver's shock propagation)
        self._largest = None  # a one-element work array (max_speed)
        # Kernels count events in a small i32 array; `collect_stats` drains it into Python
        # integers after every frame, so long runs of many particles cannot overflow it.
        self.stats = ti.ndarray(ti.i32, shape=len(STAT_NAMES))
        self.stats.fill(0)
        self.totals = dict.fromkeys(STAT_NAMES, 0)
        # `version` counts the times the state may have changed outside the impulse solver's
        # step kernel (a kernel that moves particles calls `mark_moved` first); the impulse
        # solver keeps each particle's clearance (how far it can move before it could touch
        # a collider) between launches and trusts it only while `clearance_key` (versions of
        # store and collider table at its last launch) holds.
        self.version = 0
        self.clearance_key = None
        # the clearance_key of the impulse solver's step kernel's last launch, which kept each
        # particle's separating plane (`separation`): valid while the clearances it wrote are
        # the ones kept (no other kernel wrote them since)
        self.separation_key = None
        # the substep map (gravity, dt, the law) of the impulse solver's last launch, whose
        # fixed points it marked AT_REST in the clearances (solvers/impulse.py)
        self.rest_map = None
        # `edits` counts the changes of the stored arrays from outside the kernels (writes
        # from the host, growth, permutations): what a step keeps between substeps (the
        # pair solver's neighbour lists) holds only while it is unchanged.
        self.edits = 0
        self.wakes = 0  # calls of wake_all (what the pair solver's skip watches: sleeping.all_asleep)
        # Angular velocities w (rad/s), kept only once a solver that spins particles asks for
        # them (enable_spin): the other solvers treat particles as points.
        self.w = None
        # The lowest storage slot whose position was written from the host since the pair
        # solver last gave the written particles their overlap allowances (None: none since).
        self.placed_from = None
        # `placements` counts the placements from the host (particles added as placed, positions
        # written): the solver moves particles placed inside colliders once per placement
        # (Solver.place_out)
        self.placements = 0
        self.next_id = 0  # the id the next particle added gets
        # `host_writes` counts writes of particles already in the store from the host
        # (`write`): what holds between the substeps of a run for particles as they were (the
        # DEM springs) holds no longer. Adding and removing particles leave the others alone.
        self.host_writes = 0
        self._args = None  # the argument packs, built when first asked for (see `args`)
        self._spin_args = None
        self.permuted = False  # whether the storage order may differ from ascending id
        self._slots_host = None  # the storage slot of each particle in public order (see _slots)
        self._spare = None  # arrays `permute` writes into (then swapped in)
        self._allocate(max(int(capacity), 1))

    def _stored(self) -> tuple:
        """The STORED arrays, in that order."""
        return tuple(getattr(self, name) for name in STORED)

    def _set_stored(self, arrays):
        for name, array in zip(STORED, arrays, strict=True):
            setattr(self, name, array)

    def enable_spin(self):
        """Keep an angular velocity per particle from now on (zero to start with)."""
        if self.w is None:
            self.w = _spin_array(self.capacity)
            self._w_spare = None
            self._spin_args = None
            self.edits += 1

    def _allocate(self, capacity: int):
        """Arrays of `capacity` slots, the particles kept in their slots (storage order kept)."""
        names = STORED + (("w",) if self.w is not None else ())
        old = {name: getattr(self, name).to_numpy()[: self.count] for name in names} if self.count else {}
        self._set_stored(_stored_arrays(capacity))
        self._spare = None
        if self.w is not None:
            self.w = _spin_array(capacity)
            self._w_spare = None
        self.capacity = capacity
        self.version += 1
        self.edits += 1
        self._args = self._spin_args = None
        if self.count:
            for name, values in old.items():
                self._write_range(name, 0, values)

    def _write_range(self, name: str, start: int, values: np.ndarray):
        """Storage slots start.. of one quantity: a transfer of the values alone and a copy
        kernel (the whole array's round trip through the host would cost O(capacity) for
        every few particles an emitter adds)."""
        self.version += 1
        self.edits += 1
        array = getattr(self, name)
        values = np.asarray(values)
        if not len(values):
            return
        staged = new_ndarray(array.dtype, array.element_shape, len(values))
        staged.from_numpy(np.ascontiguousarray(values, dtype=_numpy_dtype(array)))
        _copy_into(array, start, staged)

    def add(self, x, v, mass, radius, *, placed: bool = True) -> slice:
        """Append validated host arrays, each particle with the next id; returns the slice
        of the new particles in public order. placed False: they overlap nothing (an
        emitter's), so the pair solver need not look for overlap to give them allowances."""
        n = len(x)
        if self.next_id + n > MAX_IDS:
            raise ValueError(f"positions: this scene has given out {self.next_id:,} particle ids; {n:,} more would "
                             f"pass the {MAX_IDS:,} it can hold")
        if self.count + n > self.max_count:
            held = ("with particle collisions a scene holds" if self.max_count < MAX_STORED else "a scene holds")
            raise ValueError(f"positions: {held} at most {self.max_count:,} particles (Taichi's 32-bit array "
                             f"offsets); it has {self.count:,}, and {n:,} more would pass it")
        if self.count + n > self.capacity:  # (doubling, but never past what the arrays can index)
            self._allocate(max(min(2 * self.capacity, self.max_count), self.count + n))
        start = self.count
        if n:  # one launch (an emitter adds a few particles every substep)
            dtype = _numpy_dtype(self.x)
            _append(self.x, self.v, self.mass, self.radius, self.flags, self.allowance, self.rest, self.anchor,
                    self.ids, start, self.next_id, np.ascontiguousarray(x, dtype=dtype),
                    np.ascontiguousarray(v, dtype=dtype), np.ascontiguousarray(mass, dtype=dtype),
                    np.ascontiguousarray(radius, dtype=dtype))
            self.version += 1
            self.edits += 1
        self.next_id += n
        self._slots_host = None
        if n and placed:
            self.placed_from = start if self.placed_from is None else min(self.placed_from, start)
            self.placements += 1
        if self.w is not None:
            self._write_range("w", start, np.zeros_like(x))
        self.count += n
        self._count_changed()
        if n:
            self.max_radius = max(self.max_radius, float(np.max(radius)))
            self.min_radius = min(self.min_radius, float(np.min(radius)))
            lightest, heaviest = self.mass_range
            self.mass_range = (min(lightest, float(np.min(mass))), max(heaviest, float(np.max(mass))))
        return slice(start, start + n)

    def expect(self, mass: float, radius: float):
        """Particles of this mass and radius will be added (an emitter's): the bounds that
        grids, substep choices and solver checks read (max_radius, min_radius, mass_range)
        take them in now, before the first of them arrives in the middle of a frame."""
        self.max_radius = max(self.max_radius, float(radius))
        self.min_radius = min(self.min_radius, float(radius))
        lightest, heaviest = self.mass_range
        self.mass_range = (min(lightest, float(mass)), max(heaviest, float(mass)))

    def clearances_hold(self, table) -> bool:
        """Whether the kept clearances still describe the particles against the collider
        `table`: nothing moved the particles or changed the table since they were written."""
        return self.clearance_key == (self.version, table.version)

    def clearances_written(self, table):
        """A kernel has just written the clearances for the particles as it left them."""
        self.clearance_key = (self.version, table.version)

    def _slots(self) -> np.ndarray | None:
        """The storage slot of each particle in public order, ascending id (None: slot k
        holds the k-th, as while the store was never permuted: adding appends larger ids and
        compacting keeps the order)."""
        if not self.permuted:
            return None
        if self._slots_host is None:
            self._slots_host = np.argsort(self.ids.to_numpy()[: self.count], kind="stable")
        return self._slots_host

    def public_ids(self) -> np.ndarray:
        """Every particle's id (int64), ascending: the public order."""
        ids = self.ids.to_numpy()[: self.count].astype(np.int64)
        slots = self._slots()
        return ids if slots is None else ids[slots]

    def read(self, name: str) -> np.ndarray:
        """One quantity of every particle, in public order."""
        stored = getattr(self, name).to_numpy()[: self.count]
        slots = self._slots()
        return stored.copy() if slots is None else stored[slots]

    def write(self, name: str, values: np.ndarray):
        """One quantity of every particle, given in public order."""
        slots = self._slots()
        if slots is not None:
            stored = np.empty_like(np.asarray(values))
            stored[slots] = values
            values = stored
        self._write_range(name, 0, values)
        self.host_writes += 1
        if name == "x" and self.count:
            self.placed_from = 0  # every particle was placed anew
            self.placements += 1
        if name not in ("rest", "anchor"):
            self.wake_all()

    def compact(self, keep: np.ndarray):
        """Remove the particles of the slots where `keep` (bool, one per slot up to the
        count) is False; the others keep their ids and their storage order. Returns the
        order (an ndarray: slot k now holds what slot order[k] held) and the new count, for
        whatever else is kept per slot (the DEM springs)."""
        kept = np.flatnonzero(keep).astype(np.int32)
        order = ti.ndarray(ti.i32, shape=max(len(kept), 1))
        if len(kept):
            order.from_numpy(kept)
        n = len(kept)
        if n == self.count:
            return order, n
        if self.placed_from is not None:  # (slots shift down: the new ones' first slot with them)
            self.placed_from = int(np.count_nonzero(keep[: self.placed_from]))
        self._apply_order(order, n)
        self.count = n
        self._slots_host = None
        return order, n

    def wake_all(self):
        """Every sleeping particle awake, every rest time back to zero (the state was written
        from the host, gravity changed, ...: docs/physics.md 5.3.1)."""
        self.rest.fill(0.0)
        self.wakes += 1

    def permute(self, order, n: int):
        """Reorder the storage: slot k gets the particle of slot order[k] (order: an ndarray
        whose first n entries are a permutation of 0..n-1, the count). Every stored quantity
        moves with it, the clearances too (they stay valid); the public order does not change."""
        if n != self.count:
            raise ValueError(f"permute: n must be the particle count {self.count}; got {n}")
        self._apply_order(order, n)
        self.permuted = True
        self._slots_host = None

    def _apply_order(self, order, n: int):
        """Slot k gets the particle of slot order[k], k < n, for every stored quantity."""
        if self._spare is None:
            self._spare = _stored_arrays(self.capacity)
        current = self._stored()
        _permute(order, n, *current, *self._spare)
        self._set_stored(self._spare)
        self._spare = current
        if self.w is not None:
            if self._w_spare is None:
                self._w_spare = _spin_array(self.capacity)
            _permute_spin(order, n, self.w, self._w_spare)
            self.w, self._w_spare = self._w_spare, self.w
        self._args = self._spin_args = None
        self.edits += 1

    def _count_changed(self):
        """The count changed, the arrays did not: on the CPU, whose launches run to the end
        before they return, the pack's count is set in place; building a pack costs about
        0.3 ms of Python, and an emitter changes the count every substep. On GPUs, whose
        launches run after they return, a new pack, so that none in flight changes."""
        if self._args is not None and runtime.ensure_init().arch == "cpu":
            self._args["count"] = self.count
        else:
            self._args = None

    @property
    def args(self) -> ParticleArgs:
        """The store's arrays as kernels take them (types.ParticleArgs), rebuilt only when the
        arrays or the count change."""
        if self._args is None:
            self._args = ParticleArgs(count=self.count, x=self.x, v=self.v, mass=self.mass, radius=self.radius,
                                      flags=self.flags, allowance=self.allowance, rest=self.rest, anchor=self.anchor,
                                      stats=self.stats)
        return self._args

    @property
    def spin_args(self) -> SpinArgs:
        """The angular velocities as kernels take them (types.SpinArgs); enable_spin first."""
        if self._spin_args is None:
            if self.w is None:
                raise RuntimeError("spin_args: the store keeps no angular velocities; call enable_spin() first")
            self._spin_args = SpinArgs(w=self.w)
        return self._spin_args

    def mark_moved(self):
        """A kernel is about to move the particles: the clearances the impulse solver kept
        (clearances_hold) stop counting."""
        self.version += 1

    def arrays(self) -> list:
        """Every array the store holds (for memory accounting): the quantities, the second set
        `permute` writes into, and the angular velocities with theirs."""
        held = list(self._stored())
        held += list(self._spare or ())
        if self.w is not None:
            held += [self.w] + ([self._w_spare] if self._w_spare is not None else [])
        return held

    def max_speed(self) -> float:
        """The fastest active particle's speed (m/s)."""
        if self._largest is None:
            self._largest = ti.ndarray(float, shape=1)
        self._largest.fill(0)
        _max_speed_sq(self.count, self.v, self.flags, self._largest)
        return float(runtime.read_small(self._largest, 1)[0]) ** 0.5

    def collect_stats(self) -> dict:
        """Move the kernels' event counts into `totals`; returns the counts just collected."""
        fresh = dict(zip(STAT_NAMES, (int(s) for s in self.stats.to_numpy())))
        if any(fresh.values()):
            self.stats.fill(0)
            for name, count in fresh.items():
                self.totals[name] += count
        return fresh
