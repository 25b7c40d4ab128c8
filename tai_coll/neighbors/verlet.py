"""Verlet lists: neighbour lists kept from one substep to the next.

Lists built with an extra reach (the skin) hold every pair that can come within contact
reach while no particle has moved more than half the skin from where the lists saw it: two
particles approach each other by at most the sum of their displacements. So the lists are
built (HashGrid.build, with the skin added to the reach), the positions they saw recorded
(`mark`), and each later substep asks whether they still hold (`moved`, or, fused into a
kernel that passes over the particles anyway, `left_lists`). A particle whose status changed
(it left the domain, or went non-finite) also invalidates them. What the lists were built
for (the store's edit count, the particle count, the reach, ...) is the caller's key: any
change of it means a rebuild.
"""

import taichi as ti

from ..types import ACTIVE, ARRAY, vec3, vec4

#: Where the particles were when the lists were built, for kernels that check the lists while
#: they pass over the particles anyway (left_lists).
SeenArgs = ti.types.argpack(listed_at=ARRAY)


@ti.func
def left_lists(x: vec3, active, seen: vec4, reach2):
    """Whether a particle at x (active: simulated now) is no longer held by lists that saw it
    at seen.xyz (seen.w: 1 if it was simulated then, 0 if not): it moved more than
    sqrt(reach2) since, or its status changed."""
    return (active and (x - seen.xyz).norm_sqr() > reach2) or (active != (seen.w > 0.5))


@ti.kernel
def _moved(x: ARRAY, flags: ARRAY, n: ti.i32, listed_at: ARRAY, reach2: float,
           # output
           stale: ARRAY):
    """In stale[0], whether the lists no longer hold: some particle moved more than
    sqrt(reach2) from where the lists saw it, or its status changed since (left_lists)."""
    stale[0] = 0
    for i in range(n):
        if left_lists(x[i], flags[i] == ACTIVE, listed_at[i], reach2):
            stale[0] = 1


@ti.kernel
def _mark(x: ARRAY, flags: ARRAY, n: ti.i32,
          # outputs
          listed_at: ARRAY):
    for i in range(n):
        listed_at[i] = vec4(x[i], ti.select(flags[i] == ACTIVE, 1.0, 0.0))


class VerletLists:
    """Where each particle was when the lists were last built (`listed_at`: x, y, z and 1 if
    it was simulated then), what they were built for (`key`), and how often they were built.
    The lists themselves are the hash grid's (HashGrid.build)."""

    def __init__(self):
        self.listed_at = None
        self.key = None  # what the lists were built for; None: never built, or invalidated
        self.builds = 0  # times the lists were built
        self.complete = True  # whether the last build kept every neighbour in reach
        self._stale = ti.ndarray(ti.i32, shape=1)
        self._args = None

    def ensure(self, capacity: int):
        """Room for `capacity` particles."""
        if self.listed_at is None or self.listed_at.shape[0] != capacity:
            self.listed_at = ti.Vector.ndarray(4, float, shape=capacity)
            self.key = None
            self._args = None

    @property
    def args(self) -> SeenArgs:
        """`listed_at` as kernels that check the lists take it."""
        if self._args is None:
            self._args = SeenArgs(listed_at=self.listed_at)
        return self._args

    def invalidate(self):
        """The lists no longer describe the particles (the grid was sorted for something else)."""
        self.key = None

    def moved(self, x, flags, n: int, skin: float) -> bool:
        """Whether some particle has moved more than skin / 2 from where the lists saw it, or
        changed status (one pass over the particles and a read from the device)."""
        _moved(x, flags, n, self.listed_at, (0.5 * skin) ** 2, self._stale)
        return bool(self._stale[0])

    def mark(self, x, flags, n: int):
        """Record the positions x the lists were just built at (to check them against later)."""
        _mark(x, flags, n, self.listed_at)

    def built(self, key):
        """The lists were just built, for `key`."""
        self.key = key
        self.builds += 1
