"""Particles that enter and leave a running scene (docs/physics.md 8): emitters place new
particles in a region at a rate, sinks remove the particles whose centre enters a region.

Regions are the solid shapes the colliders use (Box, Sphere, Cylinder), read as volumes:
their pose is where they were built (a region does not move).

An emitter works at the start of each substep: it owes floor(rate (t1 - start)) particles by
the end t1 of the substep (t1 clipped to its stop), less those it placed or skipped before,
and places each where it overlaps no particle (in the scene or placed just now) and no
collider, trying random points of the region (ATTEMPTS per particle, from its own seeded
generator: the same seed, the same particles). What finds no room is skipped and counted.
The particles it could touch are gathered by a kernel (`Sinks.near`), so the host reads only
those, not the whole store, every substep.

A sink marks the particles whose centre lies in it after a substep (a kernel: no host
work per substep); the scene removes the marked ones at the end of the frame, compacting
the store (scene/particles.py `compact`): ids are never reused.
"""


import math

import numpy as np
import taichi as ti

from .. import notices, runtime, validate
from ..geometry.colliders import Box, Cylinder, Sphere
from ..types import ACTIVE, REMOVED, ParticleArgs, host_vector, vec3

#: Random points of the region tried per particle owed before it is skipped.
ATTEMPTS = 16
#: Kinds of region in the sinks' table (and the emitters' sampling).
BOX, SPHERE, CYLINDER = 0, 1, 2
#: The densest packing of equal spheres (Kepler): no region holds more than this fraction of its
#: volume in particles, so no more are tried at once (a hostile rate costs no more than a full region).
DENSEST = np.pi / (3.0 * np.sqrt(2.0))
#: Candidate points checked against the particles near the region at once (memory: this
#: many times the nearby particles, in float64).
CHUNK = 1 << 20
#: Candidate points an emitter spaces apart with one table of their distances (_spaced): the
#: table's temporaries take 32 B a pair, 32 MiB at this count.
PAIRWISE = 1024


def region_row(name: str, region) -> tuple:
    """(kind, centre, rotation, (a, b, c)) of a region: a Box (half extents), Sphere
    (radius, 0, 0) or Cylinder (radius, half height, 0; its axis the local y)."""
    if isinstance(region, Box):
        return BOX, region.center, region.rotation, tuple(region.half_extents)
    if isinstance(region, Sphere):
        return SPHERE, region.center, region.rotation, (region.radius, 0.0, 0.0)
    if isinstance(region, Cylinder):
        return CYLINDER, region.center, region.rotation, (region.radius, region.half_height, 0.0)
    raise TypeError(f"{name} must be a tc.Box, tc.Sphere or tc.Cylinder (a volume); got {type(region).__name__}")


def _bound(kind: int, size) -> float:
    """The radius of a sphere about the region's centre that holds it."""
    if kind == BOX:
        return float(np.linalg.norm(size))
    if kind == SPHERE:
        return float(size[0])
    return float(math.hypot(size[0], size[1]))


def _volume(kind: int, size) -> float:
    if kind == BOX:
        return 8.0 * float(np.prod(size))
    if kind == SPHERE:
        return 4.0 / 3.0 * np.pi * size[0] ** 3
    return 2.0 * np.pi * size[0] ** 2 * size[1]


def _sample(rng: np.random.Generator, kind: int, size, n: int) -> np.ndarray:
    """n points uniform in the region's local frame."""
    if kind == BOX:
        return rng.uniform(-1.0, 1.0, (n, 3)) * np.asarray(size)
    if kind == SPHERE:
        direction = rng.normal(size=(n, 3))
        direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-300)
        return direction * (size[0] * rng.uniform(0.0, 1.0, n) ** (1.0 / 3.0))[:, None]
    radius, half = size[0], size[1]
    r = radius * np.sqrt(rng.uniform(0.0, 1.0, n))
    angle = rng.uniform(0.0, 2.0 * np.pi, n)
    return np.stack([r * np.cos(angle), rng.uniform(-half, half, n), r * np.sin(angle)], axis=1)


class Emitter:
    """A source of particles (Scene.add_emitter). Reads: `emitted` and `skipped` (particles
    owed that found no room), and the settings it was made with."""

    def __init__(self, region, *, rate, velocity=(0.0, 0.0, 0.0), radius=0.005, mass=1.0, start=0.0, stop=None,
                 max_particles=None, seed=0):
        self.kind, self.center, self.rotation, self.size = region_row("region", region)
        self.region = region
        self.rate = validate.real("rate", rate, low=0.0, low_open=True, stored=False)
        self.velocity = validate.vector3("velocity", velocity)
        self.radius = validate.real("radius", radius, low=0.0, low_open=True)
        self.mass = validate.real("mass", mass, low=0.0, low_open=True)
        self.start = validate.real("start", start, low=0.0, stored=False)
        self.stop = validate.real("stop", stop, low=self.start, low_open=True, allow_none=True, stored=False)
        self.max_particles = None if max_particles is None else validate.integer("max_particles", max_particles,
                                                                                 low=0)
        self.seed = validate.integer("seed", seed, low=0)
        self.rng = np.random.default_rng(self.seed)
        self.emitted = 0
        self.skipped = 0
        # the most particles the region could hold at once (the densest packing, centres in it)
        self.room = int(DENSEST * _volume(self.kind, self.size) / (4.0 / 3.0 * np.pi * self.radius ** 3)) + 1
        self.warned = False  # whether the scene warned that it found no room (once)
        self.warned_full = False  # ... that the scene held all the particles it can (once)

    def __repr__(self):
        return (f"Emitter({type(self.region).__name__}, rate={self.rate:g}/s, radius={self.radius:g}, "
                f"mass={self.mass:g}, velocity={self.velocity.tolist()}, start={self.start:g}, stop={self.stop}, "
                f"max_particles={self.max_particles}, seed={self.seed})")

    def finished(self, t: float) -> bool:
        """Whether it will emit nothing after time t."""
        return ((self.stop is not None and t >= self.stop)
                or (self.max_particles is not None and self.emitted >= self.max_particles))

    def owed(self, t1: float) -> int:
        """Particles due by time t1 and not yet placed or skipped."""
        end = t1 if self.stop is None else min(t1, self.stop)
        due = self.rate * max(end - self.start, 0.0)
        due = math.floor(due + max(1e-9, 1e-12 * due))  # (rate * time may land a hair below a whole number)
        owed = max(due - self.emitted - self.skipped, 0)
        if self.max_particles is not None:
            owed = min(owed, self.max_particles - self.emitted)
        return max(owed, 0)

    def place(self, owed: int, x: np.ndarray, r: np.ndarray, colliders) -> np.ndarray:
        """World positions of up to `owed` new particles that overlap none of the particles
        at x (radii r: those within reach of the region, Sinks.near) nor each other nor any
        collider entry; counts what found no room."""
        if owed <= 0:
            return np.zeros((0, 3))
        tried = min(owed, self.room)  # (more than the region holds cannot fit: skipped untried)
        local = _sample(self.rng, self.kind, self.size, tried * ATTEMPTS)
        points = self.center + local @ self.rotation.T
        ok = self._clear_of_colliders(points, colliders)
        if len(x):
            # squared distances axis by axis, added in the order np.sum adds a row of three
            # (the same values; a sum over a last axis of three is NumPy's slow case)
            step = max(CHUNK // len(x), 1)
            gap2 = (r + self.radius) ** 2
            for lo in range(0, len(points), step):
                part = points[lo:lo + step]
                d2 = (part[:, 0, None] - x[None, :, 0]) ** 2
                d2 += (part[:, 1, None] - x[None, :, 1]) ** 2
                d2 += (part[:, 2, None] - x[None, :, 2]) ** 2
                ok[lo:lo + step] &= np.all(d2 >= gap2[None], axis=1)
        taken = _spaced(points[ok], (2.0 * self.radius) ** 2, tried)
        self.emitted += len(taken)
        self.skipped += owed - len(taken)
        return taken

    def _clear_of_colliders(self, points: np.ndarray, colliders) -> np.ndarray:
        """Whether a particle centred at each point is clear of every collider entry at its
        current pose (the query takes the shape's own pose: points go to its frame)."""
        ok = np.ones(len(points), dtype=bool)
        reach = _bound(self.kind, self.size) + self.radius
        for entry in colliders:
            shape = entry.shape
            if np.linalg.norm(entry.center - self.center) > reach + shape.params[shape.BOUND_SLOT]:
                continue  # (its bounding sphere is out of the region's reach)
            rest = shape.center + ((points - entry.center) @ entry.rotation) @ shape.rotation.T
            ok &= shape.signed_distance(rest) >= self.radius
        return ok

    def state(self) -> dict:
        """What the next emission reads besides the scene's time (save_state)."""
        return {"emitted": self.emitted, "skipped": self.skipped, "rng": self.rng.bit_generator.state}

    def restore(self, state: dict):
        self.emitted, self.skipped = int(state["emitted"]), int(state["skipped"])
        self.rng.bit_generator.state = state["rng"]


def _spaced(points: np.ndarray, gap2: float, most: int) -> np.ndarray:
    """The points, in order, that lie no nearer than sqrt(gap2) to any point taken before
    them, at most `most` of them. Up to PAIRWISE points (an emitter's usual few a substep), the
    squared distances between all of them are computed at once, as the loop below computes
    them one point at a time (the same values), and walked in plain Python: a NumPy call a
    point cost more than the rest of the placement."""
    if len(points) <= PAIRWISE:
        near = (np.sum((points[:, None, :] - points[None]) ** 2, axis=2) < gap2).tolist()
        taken = []
        for k, row in enumerate(near):
            if not any(row[j] for j in taken):
                taken.append(k)
                if len(taken) == most:
                    break
        return points[taken].reshape(len(taken), 3)
    placed = np.empty((most, 3))
    count = 0
    for p in points:
        if count and np.min(np.sum((placed[:count] - p) ** 2, axis=1)) < gap2:
            continue
        placed[count] = p
        count += 1
        if count == most:
            break
    return placed[:count]


def emit(emitters, store, sinks, colliders, t1: float, dt: float):
    """Each emitter's particles due by time t1 (the end of the substep of dt seconds), placed
    clear of the particles there are (any status; `sinks.near` gathers those within reach)
    and of the colliders (entries at their poses now), appended to the store."""
    for k, emitter in enumerate(emitters):
        owed = emitter.owed(t1)
        if not owed:
            continue
        x, r = sinks.near(store, emitter)
        before = emitter.skipped
        new = emitter.place(owed, x, r, colliders)
        if emitter.skipped > before and not emitter.warned:
            emitter.warned = True
            notices.warn(
                f"emitter {k} ({type(emitter.region).__name__}, {emitter.rate:g} particles/s) found no room for "
                f"{emitter.skipped - before} particle(s) at t = {t1:.6g} s: its region holds at most about "
                f"{emitter.room:,} of radius {emitter.radius:g} m and must take {emitter.rate * dt:.3g} a substep "
                "besides the particles already there (and stay clear of colliders). The count goes on in "
                "emitter.skipped (stats()['emission_skipped']); a larger region, a lower rate or a faster velocity "
                "out of it emits them all", RuntimeWarning)
        room = max(store.max_count - store.count, 0)
        full = max(len(new) - room, 0)
        if full:  # placed, but the scene holds all the particles its arrays can index (ParticleStore.max_count)
            new = new[:room]
            emitter.emitted -= full
            emitter.skipped += full
            if not emitter.warned_full:
                emitter.warned_full = True
                notices.warn(f"emitter {k} ({type(emitter.region).__name__}) skipped {full} particle(s) at "
                             f"t = {t1:.6g} s: the scene holds its most, {store.max_count:,} particles (Taichi's "
                             "32-bit array offsets). The count goes on in emitter.skipped; sinks make room",
                             RuntimeWarning)
        n = len(new)
        if n:  # (placed clear of everything: no overlap allowances to look for)
            store.add(new, np.tile(emitter.velocity, (n, 1)), np.full(n, emitter.mass), np.full(n, emitter.radius),
                      placed=False)


def remove_marked(store, sinks, pairs):
    """The particles the sinks marked this frame leave the store (ids not reused); the pair
    solver's springs follow the compaction."""
    keep = store.flags.to_numpy()[: store.count] != REMOVED
    if keep.all():
        return
    order, n = store.compact(keep)
    if pairs is not None:
        pairs.compacted(order, n, store)
    sinks.removed += int(keep.size - n)


class Sinks:
    """The scene's sinks: a table of regions on the device and the count removed; and the
    work arrays emitters gather nearby particles into (`near`)."""

    def __init__(self):
        self.regions = []
        self._rows = []  # (kind, centre, rotation row-major, size) of each region
        self.table = None
        self.removed = 0  # particles removed since the scene was built
        self._near = None  # (x, r) rows of the particles near an emitter (see near)
        self._found = None
        self._head = None  # (the first rows of _near, on their way to the host)

    def __len__(self):
        return len(self.regions)

    def add(self, region):
        kind, center, rotation, size = region_row("region", region)
        self.regions.append(region)
        self._rows.append([kind, *center, *rotation.ravel(), *size])
        rows = np.array(self._rows, dtype=runtime.float_dtype())
        self.table = ti.ndarray(float, shape=rows.shape)
        self.table.from_numpy(rows)

    def near(self, particles, emitter) -> tuple:
        """(x (K, 3), r (K,)) float64 of the particles (any status) that a new particle of
        `emitter` could touch anywhere in its region, in no particular order."""
        if not particles.count:
            return np.zeros((0, 3)), np.zeros(0)
        if self._near is None or self._near.shape[0] < particles.capacity:
            self._near = ti.Vector.ndarray(4, float, shape=particles.capacity)
            self._found = ti.ndarray(ti.i32, shape=1)
        reach = _bound(emitter.kind, emitter.size) + emitter.radius
        _gather_near(particles.args, host_vector(emitter.center), reach, self._found, self._near)
        k = int(runtime.read_small(self._found, 1)[0])
        if not k:
            return np.zeros((0, 3)), np.zeros(0)
        # the first k rows cross to the host, through a buffer kept between calls (allocating
        # one costs more than copying the rows) that grows by doubling
        if self._head is None or self._head.shape[0] < k:
            self._head = ti.Vector.ndarray(4, float, shape=max(k, 2 * (0 if self._head is None else
                                                                        self._head.shape[0])))
        _copy_head(self._near, self._head, k)
        rows = self._head.to_numpy()[:k].astype(np.float64)
        return rows[:, :3], rows[:, 3]

    def mark(self, particles):
        """Flag the active particles whose centre lies in a sink REMOVED (a kernel)."""
        _mark(particles.args, self.table, len(self.regions))


@ti.kernel
def _gather_near(particles: ParticleArgs, center: vec3, reach: float, found: ti.types.ndarray(), near: ti.types.ndarray()):
    found[0] = 0
    for i in range(particles.count):
        p = particles.x[i]
        r = particles.radius[i]
        if (p - center).norm() <= reach + r:
            near[ti.atomic_add(found[0], 1)] = ti.Vector([p[0], p[1], p[2], r])


@ti.kernel
def _copy_head(rows: ti.types.ndarray(), head: ti.types.ndarray(), count: ti.i32):
    for k in range(count):
        head[k] = rows[k]


@ti.kernel
def _mark(particles: ParticleArgs, table: ti.types.ndarray(ndim=2), sinks: ti.i32):
    for i in range(particles.count):
        if particles.flags[i] == ACTIVE:
            p = particles.x[i]
            for s in range(sinks):
                d = p - vec3(table[s, 1], table[s, 2], table[s, 3])
                # local = R^T d (R row-major in columns 4..12)
                local = vec3(0.0)
                for a in ti.static(range(3)):
                    local[a] = table[s, 4 + a] * d[0] + table[s, 7 + a] * d[1] + table[s, 10 + a] * d[2]
                kind = ti.cast(table[s, 0], ti.i32)
                a, b = table[s, 13], table[s, 14]
                inside = False
                if kind == 0:
                    inside = abs(local[0]) <= a and abs(local[1]) <= b and abs(local[2]) <= table[s, 15]
                elif kind == 1:
                    inside = local.norm_sqr() <= a * a
                else:
                    inside = abs(local[1]) <= b and local[0] * local[0] + local[2] * local[2] <= a * a
                if inside:
                    particles.flags[i] = REMOVED
