"""A scene's rigid bodies through one substep (docs/physics.md 7.1).

    begin   gravity, the bodies' contacts with colliders and each other (rigid.py), then
            each body's pose at the end of the substep predicted from its velocities: the
            collider table holds the body as a moving collider from its pose now to there;
    (the particle solver's substep: particles meet bodies like any moving collider, with the
            two-body law, booking what they give each body, response/exchange.py)
    end     the particles' impulses summed (coupling.py) and taken from each body's momentum
            and angular momentum; the pose redone from the pose now with the new velocities,
            x1 = x0 + dt v, R1 = exp(dt w) R0, and committed.
    (with impulse pairs, `end` runs inside the particles' substep, before they are stored:
            they are then kept out of the bodies at the committed poses, and what the
            particles a body pushed so got from it is taken from it, `take_pushes`)

A body's surface moves, as the particles see it, with the predicted motion; its real motion
is what the particles left it. A body a particle cannot move (the particle is held by what
it rests on) is stopped by it: the particle's share of the stop goes to the body alone.
"""

from __future__ import annotations

import numpy as np

from .. import notices
from . import rigid
from .coupling import Coupling
from .store import BodyStore, cross, orthonormal


class BodyMotion:
    """The `motion` of a body's collider entry: the table takes its poses and rates from the
    body (scene/colliders.py calls `pose` and `rates` in ColliderTable.advance)."""

    is_body = True

    def __init__(self, store: BodyStore, index: int):
        self.store = store
        self.index = index

    def pose(self, rest_center, rest_rotation, t):
        return self.store.shape_pose(self.index)

    def rates(self, pose0, pose1, dt):
        b = self.index
        store = self.store
        w = store.omega(b)
        # the velocity of the shape's origin at the end pose: the table's surface velocity
        # v + w x (p - center1) is then the body's, v_com + w x (p - com1)
        com1 = pose1[0] + pose1[1] @ store.com_local[b]
        return store.v[b] + cross(w, pose1[0] - com1), w


class BodySystem:
    def __init__(self, table):
        self.store = BodyStore()
        self.table = table
        self.coupling = Coupling(table)
        self.contacts = 0  # body contacts found in the last substep (rigid.py)
        self.held = 0  # contacts with particles held by their supports in the last substep
        self._held = ()  # those contacts (coupling.Coupling.collect)
        # warm starting of the bodies' contacts, for the solve before the particles' passes
        # and for the one after them (each from its own last solution)
        self.contact_cache = rigid.ContactCache()
        self.after_cache = rigid.ContactCache()
        self.open = False  # between begin and end of a substep
        self._warned_travel = False  # whether warn_travel has warned (once)

    @property
    def count(self) -> int:
        return self.store.count

    def max_speed(self) -> float:
        """The fastest point of any body's shape (m/s): |v| + |w| times the reach of its
        bounding sphere from the centre of mass (0.0 without bodies)."""
        store = self.store
        speed = 0.0
        for b in range(store.count):
            center, _ = store.shape_pose(b)
            shape = store.entries[b].shape
            reach = shape.params[shape.BOUND_SLOT] + float(np.linalg.norm(center - store.x[b]))
            speed = max(speed, float(np.linalg.norm(store.v[b]) + np.linalg.norm(store.omega(b)) * reach))
        return speed

    def warn_travel(self, dt: float, radius: float, time: float):
        """Warn once when a body moves more than `radius` (the smallest particle's) in a
        substep of dt (docs/physics.md 7.2): the particles' passes then meet it where it is
        predicted, far from where their impulses leave it, and it pushes them into each other."""
        if self._warned_travel:
            return
        speed = self.max_speed()
        if speed * dt > radius:
            self._warned_travel = True
            notices.warn(
                f"a rigid body moves {speed * dt * 1e3:.3g} mm in a substep (its fastest point at {speed:.3g} m/s, "
                f"dt = {dt:.3g} s) at t = {time:.6g} s, more than the smallest particle radius ({radius * 1e3:.3g} "
                f"mm): particles it crosses that fast are pushed into each other, which can add energy. Use "
                f"substeps='auto' (bodies then move at most cfl of the smallest radius a substep) or "
                f"dt <= {0.5 * radius / speed:.3g} s", RuntimeWarning)

    def begin(self, world, dt: float):
        """Before the particles' substep; the table's kinematic colliders are at this
        substep's poses (ColliderTable.advance)."""
        store = self.store
        self.open = True
        self.contacts = rigid.resolve_contacts(store, self.table, np.asarray(world.gravity, dtype=np.float64), dt,
                                               self.contact_cache)
        if len(self._held):
            # The last substep's held particles hold the body before its motion is predicted:
            # free particles near them then see a body at rest, not one falling at g dt that
            # the held ones stop afterwards (which kicked them every substep).
            body, point, normal, depth = self._held
            rigid.resolve_held(store, (body, point, normal, np.zeros_like(depth)), dt)
        predicted = [store.advanced_pose(b, dt) for b in range(store.count)]
        self._set_table_poses(predicted, dt)
        self.coupling.ensure(world.particles.capacity, store.count)
        g = np.asarray(world.gravity, dtype=np.float64)
        up = -g / np.linalg.norm(g) if np.any(g) else None
        near = None
        if world.particles.count:
            if not self.coupling.lists_bodies(store):
                # count_near finds the bodies by the table's body column: before the first
                # upload (or after a body was added) it listed none, the counts were zero, and
                # a crate set down on 16 grains at -0.13 m/s left them at +0.58 m/s
                self.coupling.upload(store, None, up)
            near = self.coupling.count_near(world, dt)
        self.coupling.upload(store, near, up)

    def end(self, world, dt: float, in_table: bool = False):
        """After the particles' substep: their impulses (and held contacts), the bodies'
        contacts again, then the committed poses. in_table: the collider table's end poses
        are set to the committed ones (the start poses stay), for the particles' last step
        of the substep (ImpulseSolver.store_out_of_bodies), which the particles' substep
        then takes before it stores them (collisions.py)."""
        store = self.store
        self.open = False
        starts = [store.shape_pose(b) for b in range(store.count)] if in_table else None  # (before the commit)
        impulses, torques, held = self.coupling.collect(store, world.particles.count)
        self._take(impulses, torques)
        self.held = rigid.resolve_held(store, held, dt)
        self._held = held
        if len(held) or np.any(impulses) or np.any(torques):
            # The particles pushed: the bodies' contacts once more, so that what presses a body
            # into a floor (grains lying on it) is held there, not carried into the next pose.
            rigid.resolve_contacts(store, self.table, np.zeros(3), dt, self.after_cache)
        else:
            self.after_cache.clear()
        for b in range(store.count):
            x1, R1 = store.advanced_pose(b, dt)
            store.x[b], store.R[b] = x1, orthonormal(R1)
            entry = store.entries[b]
            entry.center, entry.rotation = store.shape_pose(b)
            entry.velocity, entry.angular_velocity = BodyMotion(store, b).rates((entry.center, entry.rotation),
                                                                                 (entry.center, entry.rotation), dt)
        if in_table:
            self.table.replace_poses({id(store.entries[b]): (starts[b], store.shape_pose(b))
                                      for b in range(store.count)})
        # (the table keeps the substep's poses until the next substep's `advance`, or the
        # scene's commit_poses at the end of the frame)

    def take_pushes(self, world):
        """After the particles were stored out of the bodies at their committed poses
        (ImpulseSolver.store_out_of_bodies): what the particles a body pushed got from it,
        taken from its velocities for the next substep (its pose stays as committed). (The
        pushes skip held particles, so the ledger holds no held contact here.)"""
        impulses, torques, _ = self.coupling.collect(self.store, world.particles.count, keep_counts=False)
        self._take(impulses, torques)

    def _take(self, impulses, torques):
        """The impulses and torques the particles got from each body, taken from its momentum
        and angular momentum."""
        store = self.store
        for b in range(store.count):
            store.v[b] = store.v[b] - impulses[b] / store.mass[b]
            store.L[b] = store.L[b] - torques[b]

    def _set_table_poses(self, predicted, dt):
        """Each body's row of the table: from its pose now to the predicted one."""
        store = self.store
        rows = {}
        for b, (x1, R1) in enumerate(predicted):
            entry = store.entries[b]
            pose0 = store.shape_pose(b)
            pose1 = store.shape_pose(b, x1, R1)
            entry.center, entry.rotation = pose0
            entry.velocity, entry.angular_velocity = BodyMotion(store, b).rates(pose0, pose1, dt)
            rows[id(entry)] = (pose0, pose1)
        self.table.replace_poses(rows)
