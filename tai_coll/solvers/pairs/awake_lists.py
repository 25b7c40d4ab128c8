"""Lists of the awake: a substep of impulse pairs whose neighbour lists leave out the pairs of
two sleeping particles where nothing awake is near, undone and run again with whole lists if
its passes wake a particle (docs/physics.md 5.3.1; docs/design-notes.md, "Lists of the awake").

In a pile that has nearly all fallen asleep, the lists are most of a substep: every sleeping
particle still scans the 27 cells around it for partners, though the passes skip each pair of
two sleeping particles at once. So when the recent substeps woke nobody, the grid's list
kernel (HashGrid.build's awake_only) gives a sleeping particle with no awake particle within
the 27 cells around it an empty list. The lists then hold every pair with an awake particle,
and the passes do what they would do with whole lists for as long as every sleeping particle
sleeps: the pairs left out are pairs of two sleeping particles, which they skip. Once a pass
wakes a particle, its pairs with sleeping neighbours may be missing: the substep is undone
(`undo`) and run again with whole lists. Exact either way: the same state to the bit.

What a substep's passes change before the colliders' last pass stores the new state is the
work arrays (written again by the prediction), the rest times of the particles they wake (set
to sleeping.WOKEN, which no particle has at the start of a substep: update_rest, run at the end
of every substep while particles may sleep, leaves every rest time at ASLEEP, 0 or above dt),
and positions the colliders' last resort pushed (the store's x; x(t) is kept in x_start).

A substep that woke a particle costs about two; CALM substeps in a row that woke nobody are
asked for first, so a pile still settling, which wakes particles in most substeps, keeps whole
lists; and while no particle sleeps there is nothing to leave out.
"""

import taichi as ti

from ... import runtime
from ...types import ARRAY, ParticleArgs
from . import gauss_seidel
from .sleeping import ASLEEP, WOKEN

#: Whether lists of the awake are used (for comparisons: the results are the same to the bit).
AWAKE_LISTS = True
#: Substeps in a row that woke nobody before a substep is given lists of the awake (at least;
#: see Calm).
CALM = 4
MOST_CALM = 256


@ti.kernel
def undo(particles: ParticleArgs, x_start: ARRAY):
    """The store as the substep found it: the particles its passes woke asleep again, and every
    position at x(t) (x_start; undoing the last resort's pushes)."""
    for i in range(particles.count):
        if particles.rest[i] == WOKEN:
            particles.rest[i] = ASLEEP
        particles.x[i] = x_start[i]


class Calm:
    """How many substeps in a row woke nobody, and whether the next may use lists of the awake:
    after `need` of them, which doubles with each substep run again (up to MOST_CALM) and halves
    with each that was not (down to CALM)."""

    def __init__(self):
        self.substeps = 0
        self.need = CALM

    def wanted(self, may: bool) -> bool:
        """Whether this substep takes lists of the awake; may: the substep allows them (particles
        may sleep, some did at the end of the last substep, nothing from outside since; Gauss-
        Seidel passes on the CPU; no placed overlap, pushes, bodies or shock propagation)."""
        if not may:
            self.substeps = 0
        return AWAKE_LISTS and may and self.substeps >= self.need

    def woke(self, passed: bool, capacity: int, awake_only: bool) -> bool:
        """Whether this substep's passes woke a particle (passed: they ran; a read from the
        device), counted; awake_only: the substep had lists of the awake (run again if woke)."""
        woke = passed and bool(runtime.read_small(gauss_seidel.pass_work(capacity).woke, 1)[0])
        self.substeps = 0 if woke else self.substeps + 1
        if awake_only:
            self.need = min(2 * self.need, MOST_CALM) if woke else max(self.need // 2, CALM)
        return woke


def again(pairs, particles):
    """Undo a substep of lists of the awake whose passes woke a particle, up to its passes: the
    store as it found it (undo), the same candidates (predicted again from it) and whole lists
    from the same sort (the neighbours it left out counted once). Returns the contact counts, as
    ParticleCollisions._predict_and_list does."""
    predict, launch, listed, dropped = pairs.redo
    undo(particles.args, pairs.delta)
    predict(**launch)
    pairs.grid.overflow[0] = dropped
    pairs.grid.relist(**listed)
    return pairs.grid.touching
