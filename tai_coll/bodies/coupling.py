"""The particles' side of two-way coupling (docs/physics.md 7.2 and 7.3): what the particle
kernels see of each body, and the sum of what they gave the bodies in a substep.

Before a substep's particle passes, `upload` writes each body's row of the collider table
(`ColliderArgs.body*`): its index, its inverse mass and world inverse inertia multiplied by
the number of particles that touched it in the previous substep (mass splitting), and its
centre of mass. The particle kernels book every impulse they give a body in their ledger
(response/exchange.py); `collect` then sums the ledger body by body in a fixed order
(serially on the CPU, so the sums are the same bit for bit in every run), clears it, and
returns the totals with the number of particles that touched each body.
"""


import numpy as np
import taichi as ti

from .. import runtime
from ..response.exchange import BODY_MASK, HELD_BIT
from ..solvers.detection import BOUND_SLOT, collider_sdf
from ..types import ACTIVE, ARRAY, ColliderArgs, ParticleArgs

# Rows of the collect kernel's output per body: impulse and torque the free particles got
# from it, and the counts (x: free particles, y: held ones, response/exchange.py `held`).
OUT_ROWS = 3


class Coupling:
    def __init__(self, table):
        self.table = table
        self.capacity = 0  # particles the ledger has slots for
        self.body_rows = 0  # bodies body_total has rows for
        self.counts = np.zeros(0)  # particles that touched each body in the last substep
        self._out = None
        self._near = None
        self._listed = None  # the bodies' entries as the table's body column last listed them (upload)

    def ensure(self, particle_capacity: int, bodies: int):
        """Ledger slots for particle_capacity particles and rows for `bodies` bodies."""
        if particle_capacity > self.capacity or bodies > self.body_rows:
            self.capacity = max(particle_capacity, self.capacity, 1)
            self.body_rows = max(bodies, self.body_rows, 1)
            ledger_body = ti.ndarray(ti.i32, shape=2 * self.capacity)
            ledger_body.fill(-1)
            ledger_impulse = ti.Vector.ndarray(3, float, shape=2 * self.capacity)
            ledger_torque = ti.Vector.ndarray(3, float, shape=2 * self.capacity)
            body_total = ti.Vector.ndarray(3, float, shape=2 * self.body_rows)
            body_total.fill(0.0)
            self.table.set_ledger(ledger_body, ledger_impulse, ledger_torque, body_total)
            self._out = ti.Vector.ndarray(3, float, shape=OUT_ROWS * self.body_rows)
            # the held contacts, listed in ledger order: body, point, normal (times 1 + depth)
            self._held_body = ti.ndarray(ti.i32, shape=2 * self.capacity + 1)
            self._held_point = ti.Vector.ndarray(3, float, shape=2 * self.capacity)
            self._held_normal = ti.Vector.ndarray(3, float, shape=2 * self.capacity)
        if len(self.counts) < bodies:
            self.counts = np.concatenate([self.counts, np.zeros(bodies - len(self.counts))])

    def arrays(self) -> list:
        """The per-particle arrays (the ledger and the held contacts' list), once allocated."""
        if not self.capacity:
            return []
        table = self.table
        return [table.ledger_body, table.ledger_impulse, table.ledger_torque, self._held_body, self._held_point,
                self._held_normal]

    def count_near(self, world, dt: float):
        """How many particles may touch each body in the coming substep: within a radius of
        touching it, beyond the way they close in on it in dt (the body's predicted pose in
        the table). These counts split the body's mass (an over-count only makes the body
        take a substep longer to follow its particles; an under-count would let many at once
        throw it)."""
        table = self.table
        particles = world.particles
        if self._near is None or self._near.shape[0] < self.body_rows:
            self._near = ti.ndarray(ti.i32, shape=self.body_rows)
        self._near.fill(0)
        _count_near(particles.args, table.args, table.groups, dt, self._near)
        return self._near.to_numpy()

    def lists_bodies(self, store) -> bool:
        """Whether the table's body column (which upload writes, and count_near reads to
        know which entries are bodies) lists the store's bodies where they are now: not
        before the first upload, nor after a body was added or the table reallocated."""
        return self._listed == self._listing(store)

    def _listing(self, store):
        index = {id(e): k for k, e in enumerate(self.table.entries)}
        return (id(self.table.body), self.table.capacity, tuple(index.get(id(e), -1) for e in store.entries))

    def upload(self, store, near=None, up=None):
        """Each body's row of the collider table for the coming substep (docs/physics.md 7.2);
        near: this substep's counts of particles near each body (count_near); up: the up
        direction (against gravity; None without gravity) for bodies resting on what holds
        them (store.supported)."""
        table = self.table
        dtype = runtime.float_dtype()
        n = len(table.entries)
        body = np.full(table.capacity, -1, dtype=np.int32)
        inv_mass = np.zeros(table.capacity, dtype=dtype)
        inv_inertia = np.zeros((table.capacity, 3, 3), dtype=dtype)
        com = np.zeros((table.capacity, 3), dtype=dtype)
        held_up = np.zeros((table.capacity, 3), dtype=dtype)
        index = {id(e): k for k, e in enumerate(table.entries[:n])}
        for b in range(store.count):
            k = index[id(store.entries[b])]
            share = max(1.0, float(self.counts[b]), 0.0 if near is None else float(near[b]))
            body[k] = b
            inv_mass[k] = share / store.mass[b]
            inv_inertia[k] = share * store.inv_inertia_world(b)
            com[k] = store.x[b]
            if up is not None and store.supported[b]:
                held_up[k] = up
        table.body.from_numpy(body)
        table.body_inv_mass.from_numpy(inv_mass)
        table.body_inv_inertia.from_numpy(inv_inertia)
        table.body_com.from_numpy(com)
        table.body_up.from_numpy(held_up)
        self._listed = self._listing(store)

    def collect(self, store, particle_count: int, keep_counts: bool = True):
        """Sum and clear the ledger: (impulses (B, 3) and torques (B, 3) the free particles
        got from each body this substep, float64; the held contacts (body (H,), point (H, 3),
        unit normal (H, 3) out of the body, depth (H,) in m), in ledger order); with
        keep_counts, the counts of the particles that touched each body are kept for the next
        upload."""
        B = store.count
        serial = runtime.info().arch == "cpu"
        _collect(self.table.ledger_body, self.table.ledger_impulse, self.table.ledger_torque, self.table.body_total,
                 particle_count, B, serial, self._out, self._held_body, self._held_point, self._held_normal)
        out = self._out.to_numpy().astype(np.float64)[:OUT_ROWS * B].reshape(B, OUT_ROWS, 3)
        if keep_counts:
            self.counts[:B] = out[:, 2, 0] + out[:, 2, 1]
        count = int(self._held_body[2 * self.capacity])
        held = ()
        if count:
            normal = self._held_normal.to_numpy()[:count].astype(np.float64)
            size = np.linalg.norm(normal, axis=1)
            held = (self._held_body.to_numpy()[:count], self._held_point.to_numpy()[:count].astype(np.float64),
                    normal / size[:, None], size - 1.0)
        return out[:, 0], out[:, 1], held


@ti.func
def _collect_slot(ledger_body: ti.template(), ledger_impulse: ti.template(), ledger_torque: ti.template(), k,
                  out: ti.template(), held_body: ti.template(), held_point: ti.template(),
                  held_normal: ti.template(), serial: ti.template()):
    entry = ledger_body[k]
    if entry >= 0:
        b = entry & BODY_MASK
        if (entry & HELD_BIT) != 0:
            last = held_body.shape[0] - 1  # (the list's length lives in its last element)
            h = 0
            if ti.static(serial):
                h = held_body[last]
                held_body[last] = h + 1
            else:
                h = ti.atomic_add(held_body[last], 1)
            held_body[h] = b
            held_point[h] = ledger_impulse[k]
            held_normal[h] = ledger_torque[k]
            out[OUT_ROWS * b + 2][1] += 1.0
        else:
            out[OUT_ROWS * b] += ledger_impulse[k]
            out[OUT_ROWS * b + 1] += ledger_torque[k]
            out[OUT_ROWS * b + 2][0] += 1.0
        ledger_body[k] = -1


@ti.kernel
def _collect(ledger_body: ARRAY, ledger_impulse: ARRAY, ledger_torque: ARRAY, body_total: ARRAY, count: ti.i32,
             bodies: ti.i32, serial: ti.template(), out: ARRAY, held_body: ARRAY, held_point: ARRAY,
             held_normal: ARRAY):
    for b in range(bodies):
        for row in ti.static(range(OUT_ROWS)):
            out[OUT_ROWS * b + row] = ti.math.vec3(0.0, 0.0, 0.0)
        out[OUT_ROWS * b] = body_total[2 * b]
        out[OUT_ROWS * b + 1] = body_total[2 * b + 1]
        body_total[2 * b] = ti.math.vec3(0.0, 0.0, 0.0)
        body_total[2 * b + 1] = ti.math.vec3(0.0, 0.0, 0.0)
    held_body[held_body.shape[0] - 1] = 0
    if ti.static(serial):
        # one pass in ledger (particle) order: the same sums and list, bit for bit, every run
        ti.loop_config(serialize=True)
        for k in range(2 * count):
            _collect_slot(ledger_body, ledger_impulse, ledger_torque, k, out, held_body, held_point, held_normal,
                          True)
    else:
        for k in range(2 * count):
            _collect_slot(ledger_body, ledger_impulse, ledger_torque, k, out, held_body, held_point, held_normal,
                          False)


@ti.kernel
def _count_near(particles: ParticleArgs, colliders: ColliderArgs, groups: ti.template(), dt: float, near: ARRAY):
    for i in range(particles.count):
        if particles.flags[i] == ACTIVE:
            xi = particles.x[i]
            ri = particles.radius[i]
            for ci in range(colliders.count):
                b = colliders.body[ci]
                if b >= 0:
                    way = (particles.v[i] - colliders.velocity[ci]).norm() * dt + \
                        colliders.angular_velocity[ci].norm() * colliders.params[ci][BOUND_SLOT] * dt
                    reach = 2.0 * ri + way
                    if (xi - colliders.center1[ci]).norm() - colliders.params[ci][BOUND_SLOT] < reach:
                        phi, n = collider_sdf(colliders, groups, ci, xi, True, reach)
                        if phi < reach:
                            ti.atomic_add(near[b], 1)
