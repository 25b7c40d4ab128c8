"""The tangential springs' memory (DEM pairs with tangential_springs, docs/physics.md 5): each
particle keeps the springs of up to HISTORY contacts from one substep to the next.

Two sets of arrays: each substep the force kernel reads last substep's springs from one set
and writes this substep's, for the contacts touching now, to the other (a contact that ended
is forgotten), then the sets swap roles. A spring is found again by its partner's id (the
store's `ids`), so the springs survive the store's reordering by cell, which moves them
with their particles (`permute`), and survive particles added (an emitter's) and removed (a
sink's: `permute` by the store's compaction order; a spring whose partner is gone is not found
again, and forgotten). Writing particles' state from the host (set_positions, ...) empties
them: a spring is only carried between the substeps of a run.
"""

import functools

import numpy as np

import taichi as ti

from ...types import ARRAY, TABLE

# Contacts whose spring a particle carries from one substep to the next; a particle touching
# more holds the rest by the regularised friction (response/penalty.py friction_force) and
# counts them in `overflow`.
HISTORY = 12

#: The springs as the force kernel reads them (last substep's: held[i] springs of particle i,
#: partner[i, h] the public id of the particle spring h touches, stretch[i, h] its tangential
#: displacement) and writes them (this substep's: next_...), and the overflow counter.
Springs = ti.types.argpack(held=ARRAY, partner=TABLE, stretch=TABLE, next_held=ARRAY, next_partner=TABLE,
                           next_stretch=TABLE, overflow=ARRAY)
#: The same for spinning particles, with a rolling spring per contact (roll, next_roll).
RollingSprings = ti.types.argpack(held=ARRAY, partner=TABLE, stretch=TABLE, roll=TABLE, next_held=ARRAY,
                                  next_partner=TABLE, next_stretch=TABLE, next_roll=TABLE, overflow=ARRAY)


@functools.cache
def _permute_kernel(rolling: bool):
    SpringsType = RollingSprings if rolling else Springs

    @ti.kernel
    def permute(order: ARRAY, n: ti.i32, springs: SpringsType):
        """Slot k of the next set gets the springs of slot order[k] of the current one (as
        ParticleStore.permute moves the particles)."""
        for k in range(n):
            i = order[k]
            springs.next_held[k] = springs.held[i]
            for h in range(HISTORY):
                springs.next_partner[k, h] = springs.partner[i, h]
                springs.next_stretch[k, h] = springs.stretch[i, h]
                if ti.static(rolling):
                    springs.next_roll[k, h] = springs.roll[i, h]

    return permute


def _spring_set(capacity: int, rolling: bool) -> dict:
    rows = (capacity, HISTORY)
    arrays = dict(held=ti.ndarray(ti.i32, shape=capacity), partner=ti.ndarray(ti.i32, shape=rows),
                  stretch=ti.Vector.ndarray(3, float, shape=rows))
    if rolling:
        arrays["roll"] = ti.Vector.ndarray(3, float, shape=rows)
    return arrays


class SpringHistory:
    """The two sets of springs, which of them holds last substep's (`current`), and the
    argument packs that read one and write the other."""

    def __init__(self):
        self.sets = None
        self.rolling = False
        self.current = 0  # the set holding last substep's springs
        self.key = None  # the store's count of host writes the springs describe
        self.slots = 0  # the store's slots below this hold springs (above: none yet)
        self.overflow = ti.ndarray(ti.i32, shape=1)
        self.overflow.fill(0)
        self._packs = None

    def fit(self, store, rolling: bool):
        """Arrays for the store's capacity (with rolling springs when the particles spin), and
        no springs when particles were written from the host since the last substep; particles
        added since then start with none."""
        if self.sets is None or self.rolling != rolling:
            self.sets = [_spring_set(store.capacity, rolling), _spring_set(store.capacity, rolling)]
            self.rolling = rolling
            self.current = 0
            self.key = None
            self._packs = None
        elif self.sets[0]["held"].shape[0] != store.capacity:  # the store grew, its slots kept: so are the springs
            grown = [_spring_set(store.capacity, rolling), _spring_set(store.capacity, rolling)]
            for old, new in zip(self.sets, grown):
                for name, array in old.items():
                    values = np.zeros(new[name].shape + tuple(array.element_shape), dtype=array.to_numpy().dtype)
                    values[: array.shape[0]] = array.to_numpy()
                    new[name].from_numpy(values)
            self.sets = grown
            self._packs = None
        if self.key != store.host_writes:
            self.sets[self.current]["held"].fill(0)
            self.key = store.host_writes
        elif store.count > self.slots:  # particles added since: no springs (their slots may hold old ones)
            held = self.sets[self.current]["held"]
            values = held.to_numpy()
            values[self.slots: store.count] = 0
            held.from_numpy(values)
        self.slots = store.count

    @property
    def args(self):
        """The pack reading the current set and writing the other (Springs or RollingSprings)."""
        if self._packs is None:
            pack = RollingSprings if self.rolling else Springs
            self._packs = [pack(**self.sets[c], **{"next_" + k: v for k, v in self.sets[1 - c].items()},
                                overflow=self.overflow) for c in (0, 1)]
        return self._packs[self.current]

    def swap(self):
        """The set just written holds the current springs."""
        self.current = 1 - self.current

    def permute(self, order, n: int, store):
        """Move the springs with their particles (the store was just permuted by `order`)."""
        if self.sets is None or self.key is None:
            return
        _permute_kernel(self.rolling)(order, n, self.args)
        self.swap()
        self.slots = n

    def arrays(self) -> list:
        """Every array the springs hold (for memory accounting)."""
        return [] if self.sets is None else [a for s in self.sets for a in s.values()]

    @property
    def overflowed(self) -> int:
        """Contacts beyond HISTORY summed over the substeps so far (a read from the device)."""
        return int(self.overflow[0])
