"""The user's settings of particle-particle collisions (Scene.enable_particle_collisions), a
small validated object apart from the pair solver's work arrays (collisions.py)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ... import notices, validate
from ...materials import Material
from .sleeping import SLEEP_DRIFT, SLEEP_TIME, WAKE_SPEED

# How the passes visit the pairs, and the defaults of each: (contact passes, projection passes,
# relaxation). Gauss-Seidel converges in fewer passes (gauss_seidel.py; docs/design-notes.md
# has the tuning that chose them).
METHODS = {"gauss-seidel": (1, 3, 1.0), "jacobi": (4, 4, 1.5)}
#: contact_margin's default, in radii of the smaller particle of each pair.
MARGIN_RADII = 0.25
TANGENTIAL_RATIO = 2.0 / 7.0  # default k_t / k_n (and D_t / D_n) of the tangential springs
#: max_push_speed's default (m/s): a half-radius overlap of 5 mm particles goes in 5 ms.
MAX_PUSH_SPEED = 0.5


def _flag(name: str, value) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False; got {type(value).__name__}")
    return bool(value)


@dataclass(frozen=True)
class PairSettings:
    """How particles collide with each other (docs/physics.md 5).

    material: restitution and friction between particles (tc.Material).
    method: "gauss-seidel" (default) or "jacobi": how the impulse passes visit the pairs.
    iterations: contact passes per substep (default 1 Gauss-Seidel, 4 Jacobi); more resolve
        piles better, cost more.
    projection_iterations: position passes removing remaining overlap (default 3
        Gauss-Seidel, 4 Jacobi).
    relaxation: over-relaxation of the contact and projection passes (1: none; up to 2;
        default 1 Gauss-Seidel, 1.5 Jacobi).
    contact_margin: m, extra reach of the impulse passes' neighbour lists, so that contacts
        created while the passes move particles are still seen (the passes move a particle
        by at most dt times its change of velocity; a contact missed in one substep is found
        in the next). None (default): a quarter of the smaller radius of each pair. Larger
        margins cost time: every listed neighbour is evaluated in every pass. (DEM pairs need
        none: their forces are evaluated once, at the substep's start.)
    verlet_skin: m, further reach of the lists so that they can be kept from one substep to
        the next (Verlet lists, neighbors/verlet.py): rebuilt only once some particle has
        moved more than half the skin from where the lists saw it (or changed status, or the
        store was written). 0 (default): rebuilt every substep. For impulse pairs this pays
        where every particle is nearly still; where a few keep moving the lists are rebuilt
        anyway and every pass evaluates the longer lists. DEM pairs: the force kernel reads
        lists of the pairs within r_i + r_j + skin instead of querying the grid, sorted anew,
        every substep; DEM substeps are short, so the lists last many of them (where a
        particle has more neighbours than the lists keep, the kernel queries the grid until
        they are next built: no contact is missed).
    reorder: put the particle store in the order of the grid's cells (before a rebuild of
        the lists, at most every REORDER_INTERVAL builds), so that neighbours lie near each
        other in memory. The public order (positions(), velocities(), ...) never changes.
    tangential_springs: DEM pairs only: friction by a spring per contact that remembers the
        contact's tangential displacement since it formed (Cundall and Strack), so static
        friction holds a contact still under a steady load, where the default regularised
        friction lets it slip by about dt^2 times the load's acceleration every substep. Costs
        HISTORY springs of memory per particle (twice: each substep reads last substep's set
        and writes the other). With spinning particles each contact also keeps a rolling
        spring.
    tangential_ratio: k_t / k_n and D_t / D_n of the tangential springs (default 2/7).
    max_push_speed: m/s, how fast overlap that particles were placed with (added
        overlapping, or moved onto each other by set_positions) is removed. It is an error of
        position, not a collision (docs/physics.md 5): impulse pairs remove it by moving
        positions only, at most max_push_speed * dt a substep, giving no particle any velocity;
        DEM pairs likewise, after each substep, their springs pressing only the overlap beyond
        it (docs/physics.md 5.2.1). Default 0.5 m/s, for particles of millimetres to
        centimetres; math.inf: placed overlap is resolved like any other (the old behaviour,
        for tests of the laws on chosen overlaps).
    sleep_time: s; a particle that stays within sleep_drift of its radius of where it came to
        rest for this long, held by its contacts, falls asleep: it stops and does not move
        until something wakes it (docs/physics.md 5.3.1), so a pile comes to rest instead of
        trembling at the speed gravity adds in a substep. "auto" (default): 0.3 s with
        Gauss-Seidel, which suits piles of millimetre to centimetre particles, and no sleeping
        with Jacobi (which has none); None: no sleeping.
    sleep_drift: that distance, as a fraction of the particle's radius (default 0.3).
    wake_speed: m/s; an awake particle that closes in on a sleeping one faster than this, or
        moves near it that fast, wakes it (default 0.05, for particles of millimetres to
        centimetres); slower, it meets the sleeping one as a wall.
    margin, skin: the old, dimensionless forms of contact_margin and verlet_skin (fractions of
        the largest particle radius), kept with a DeprecationWarning.
    """

    material: Material = Material()
    method: str = "gauss-seidel"
    iterations: int | None = None
    projection_iterations: int | None = None
    relaxation: float | None = None
    contact_margin: float | None = None
    verlet_skin: float = 0.0
    reorder: bool = True
    tangential_springs: bool = False
    tangential_ratio: float = TANGENTIAL_RATIO
    max_push_speed: float = MAX_PUSH_SPEED
    sleep_time: float | str | None = "auto"
    sleep_drift: float = SLEEP_DRIFT
    wake_speed: float = WAKE_SPEED
    margin: float | None = None
    skin: float | None = None

    def __post_init__(self):
        put = lambda name, value: object.__setattr__(self, name, value)  # noqa: E731 (a frozen dataclass)
        if self.material is None:
            put("material", Material())
        elif not isinstance(self.material, Material):
            raise TypeError(f"material must be a tc.Material; got {type(self.material).__name__}")
        put("reorder", _flag("reorder", self.reorder))
        put("tangential_springs", _flag("tangential_springs", self.tangential_springs))
        if not isinstance(self.method, str) or self.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(map(repr, METHODS))}; got {self.method!r}")
        iterations, projection_iterations, relaxation = METHODS[self.method]
        put("iterations", validate.integer("iterations", iterations if self.iterations is None else self.iterations,
                                           low=1))
        put("projection_iterations", validate.integer(
            "projection_iterations",
            projection_iterations if self.projection_iterations is None else self.projection_iterations, low=0))
        put("relaxation", validate.real("relaxation", relaxation if self.relaxation is None else self.relaxation,
                                        low=0.0, high=2.0, low_open=True))
        put("contact_margin", validate.real("contact_margin", self.contact_margin, low=0.0, allow_none=True))
        put("verlet_skin", validate.real("verlet_skin", self.verlet_skin, low=0.0))
        put("tangential_ratio", validate.real("tangential_ratio", self.tangential_ratio, low=0.0, low_open=True))
        if self.max_push_speed != math.inf:  # (inf: placed overlap is a collision like any other)
            put("max_push_speed", validate.real("max_push_speed", self.max_push_speed, low=0.0, low_open=True))
        if isinstance(self.sleep_time, str):
            if self.sleep_time != "auto":
                raise ValueError(f'sleep_time must be "auto", None or seconds; got {self.sleep_time!r}')
            put("sleep_time", SLEEP_TIME if self.method == "gauss-seidel" else None)
        elif self.method != "gauss-seidel" and self.sleep_time is not None:
            raise ValueError(f"sleep_time: particles sleep with method='gauss-seidel' only; got "
                             f"{self.sleep_time!r} with method={self.method!r} (give None)")
        put("sleep_time", validate.real("sleep_time", self.sleep_time, low=0.0, low_open=True, allow_none=True))
        put("sleep_drift", validate.real("sleep_drift", self.sleep_drift, low=0.0, low_open=True))
        put("wake_speed", validate.real("wake_speed", self.wake_speed, low=0.0))
        for old, new in (("margin", "contact_margin"), ("skin", "verlet_skin")):
            value = getattr(self, old)
            if value is None:
                continue
            if (new == "contact_margin" and self.contact_margin is not None) or (new == "verlet_skin"
                                                                                 and self.verlet_skin):
                raise TypeError(f"give {new}= (m) or its old form {old}= (radii), not both")
            notices.warn(f"enable_particle_collisions: {old}= (a fraction of the largest radius) is now {new}= in "
                          f"metres; the old name will be removed in tai_coll 0.3", DeprecationWarning)
            put(old, validate.real(old, value, low=0.0))

    def margin_length(self, largest_radius: float) -> float:
        """The largest contact margin in m, that of a pair of particles of `largest_radius`."""
        length, radii = self.margin_terms()
        return length + radii * largest_radius

    def margin_terms(self) -> tuple:
        """The contact margin of a pair as (m, radii): margin = m + radii * min(r_i, r_j); the
        default, MARGIN_RADII of the smaller radius, keeps a small particle's list as short
        beside a large one as among its likes."""
        if self.contact_margin is not None:
            return self.contact_margin, 0.0
        return 0.0, MARGIN_RADII if self.margin is None else self.margin

    def skin_length(self, largest_radius: float) -> float:
        """The Verlet skin in m for particles whose largest radius is `largest_radius`."""
        if self.skin is not None:
            return self.skin * largest_radius
        return self.verlet_skin
