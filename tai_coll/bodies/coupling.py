"""The particles' side of two-way coupling (docs/physics.md 6.2 and 6.3): what the particle
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
from ..types import ARRAY

# Rows of the collect kernel's output per body: impulse, torque, and the count (in x).
OUT_ROWS = 3


class Coupling:
    def __init__(self, table):
        self.table = table
        self.capacity = 0  # particles the ledger has slots for
        self.body_rows = 0  # bodies body_total has rows for
        self.counts = np.zeros(0)  # particles that touched each body in the last substep
        self._out = None

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
        if len(self.counts) < bodies:
            self.counts = np.concatenate([self.counts, np.zeros(bodies - len(self.counts))])

    def upload(self, store):
        """Each body's row of the collider table for the coming substep (docs/physics.md 6.2)."""
        table = self.table
        dtype = runtime.float_dtype()
        n = len(table.entries)
        body = np.full(table.capacity, -1, dtype=np.int32)
        inv_mass = np.zeros(table.capacity, dtype=dtype)
        inv_inertia = np.zeros((table.capacity, 3, 3), dtype=dtype)
        com = np.zeros((table.capacity, 3), dtype=dtype)
        index = {id(e): k for k, e in enumerate(table.entries[:n])}
        for b in range(store.count):
            k = index[id(store.entries[b])]
            share = max(1.0, float(self.counts[b]))
            body[k] = b
            inv_mass[k] = share / store.mass[b]
            inv_inertia[k] = share * store.inv_inertia_world(b)
            com[k] = store.x[b]
        table.body.from_numpy(body)
        table.body_inv_mass.from_numpy(inv_mass)
        table.body_inv_inertia.from_numpy(inv_inertia)
        table.body_com.from_numpy(com)

    def collect(self, store, particle_count: int):
        """Sum and clear the ledger: (impulses (B, 3) and torques (B, 3) the particles got
        from each body this substep, float64); the counts are kept for the next upload."""
        B = store.count
        serial = runtime.info().arch == "cpu"
        _collect(self.table.ledger_body, self.table.ledger_impulse, self.table.ledger_torque, self.table.body_total,
                 particle_count, B, serial, self._out)
        out = self._out.to_numpy().astype(np.float64)[:OUT_ROWS * B].reshape(B, OUT_ROWS, 3) if B else \
            np.zeros((0, OUT_ROWS, 3))
        self.counts[:B] = out[:, 2, 0]
        return out[:, 0], out[:, 1]


@ti.kernel
def _collect(ledger_body: ARRAY, ledger_impulse: ARRAY, ledger_torque: ARRAY, body_total: ARRAY, count: ti.i32,
             bodies: ti.i32, serial: ti.template(), out: ARRAY):
    for b in range(bodies):
        out[3 * b] = body_total[2 * b]
        out[3 * b + 1] = body_total[2 * b + 1]
        out[3 * b + 2] = ti.math.vec3(0.0, 0.0, 0.0)
        body_total[2 * b] = ti.math.vec3(0.0, 0.0, 0.0)
        body_total[2 * b + 1] = ti.math.vec3(0.0, 0.0, 0.0)
    if ti.static(serial):
        # one pass in particle order: the same sums, bit for bit, in every run
        ti.loop_config(serialize=True)
        for k in range(2 * count):
            b = ledger_body[k]
            if b >= 0:
                out[3 * b] += ledger_impulse[k]
                out[3 * b + 1] += ledger_torque[k]
                out[3 * b + 2][0] += 1.0
                ledger_body[k] = -1
    else:
        for k in range(2 * count):
            b = ledger_body[k]
            if b >= 0:
                ti.atomic_add(out[3 * b], ledger_impulse[k])
                ti.atomic_add(out[3 * b + 1], ledger_torque[k])
                ti.atomic_add(out[3 * b + 2][0], 1.0)
                ledger_body[k] = -1
