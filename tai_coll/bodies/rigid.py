"""Contacts of rigid bodies with the colliders of a scene and with each other: sequential
impulses with restitution and Coulomb friction, speculative contacts, and position
correction by pseudo-velocities (docs/physics.md 7.4; 2, "Two movable bodies"; 3, moving
colliders).

`resolve_contacts` runs once at the start of every substep, with each body's collider-table
entry at its current pose and the kinematic colliders already advanced (start pose
center0/rotation0, surface motion velocity/angular_velocity). Its phases:

1. gravity: v += g dt for every body;
2. broad phase (host): the pairs (body, collider) whose bounding spheres come within one
   substep's reach; never a body and its own entry;
3. narrow phase (kernel `_detect`): every surface sample of the body (samples.py) against
   the collider's signed distance at its start pose, one fixed slot per (sample, collider):
   the gap phi - r, the collider's outward normal and its surface velocity. A sample within
   margin + |v_rel| dt of the surface is a contact, touching or not yet (speculative);
4. gather (host): the slots that hold a contact, in slot order, with their materials and
   lever arms;
5. velocity solve (serialized kernel `_solve`): Gauss-Seidel over the contacts with
   accumulated-impulse clamping, both bodies' inverse mass and world inverse inertia;
6. position correction (same kernel): pseudo-velocities push penetrating samples out, and
   move x and R without adding real velocity.

The store's v and L change by the impulses (in float64 on the host, so a body without
contacts keeps its momentum exactly), its x and R by the position correction only; the
caller integrates the pose. Deterministic on the CPU: detection writes fixed slots, the
gather keeps slot order and the solve is serial.
"""

import numpy as np
import taichi as ti

from .. import runtime
from ..geometry.dispatch import world_sdf
from ..geometry.frames import rotation_from_vector
from ..response.exchange import SUPPORT_COS
from ..types import ColliderArgs, vec3
from .samples import surface_samples
from .store import orthonormal

#: Gauss-Seidel passes over the contacts of a substep for the velocities, and for the
#: pseudo-velocities of the position correction.
VELOCITY_ITERATIONS = 16
POSITION_ITERATIONS = 8
#: Speculative margin (m): a sample this close to a surface has a contact even when it does
#: not approach it (its constraint lets it close the gap, no more).
MARGIN = 2e-3
#: Penetration (m) left alone by the position correction: resting contacts stay touching
#: instead of flickering between touching and apart.
SLOP = 2e-4
#: The fraction of the penetration beyond SLOP removed per substep (Baumgarte's factor on the
#: pseudo-velocities), and the fastest the correction pushes (m/s): bodies spawned into one
#: another come apart over a few substeps, never thrown.
CORRECTION = 0.3
MAX_PUSH_SPEED = 1.0
#: Approaches slower than BOUNCE_FACTOR |g| dt get no restitution: a resting contact meets
#: the surface at |g| dt every substep and must not bounce. The floor (m/s) keeps round-off
#: from bouncing without gravity.
BOUNCE_FACTOR = 2.0
BOUNCE_FLOOR = 1e-6

INFINITY = 1e30
#: (A contact holds a body up when its normal is within acos(SUPPORT_COS) of up, as
#: solvers/pairs/shock.py's supports: response/exchange.py's SUPPORT_COS.)
# Columns of the packed arrays the two kernels take (one row per sample, slot, contact, body).
SAMPLE_COLUMNS = 7   # position (3), radius, velocity (3)
FOUND_COLUMNS = 7    # gap, normal (3), surface velocity (3)
CONTACT_COLUMNS = 19  # normal (3), arm a (3), arm b (3), surface velocity (3), gap, restitution, friction,
#                       warm start: normal impulse, friction impulse (3, world)
BODY_COLUMNS = 16    # v (3), w (3), inverse mass, world inverse inertia (9, row-major)
WORK_COLUMNS = 16    # tangents (6), effective masses n, t1, t2, target, impulses n, t1, t2, target_p, impulse_p
TOTAL_COLUMNS = 12   # linear impulse (3), angular impulse (3), pseudo-velocity (3), pseudo angular velocity (3)


def combined_material(body_material, collider_material):
    """(restitution, friction) of a contact: the larger restitution, so a bouncy ball bounces
    on a dead floor, and the geometric mean of the friction coefficients (Box2D's rule: a
    frictionless side makes a frictionless contact)."""
    return (max(body_material.restitution, collider_material.restitution),
            float(np.sqrt(body_material.friction * collider_material.friction)))


class ContactCache:
    """The impulses of the last substep's contacts, to start the next solve from (warm
    starting): a resting contact then needs only the change of its impulse, and a stack's
    Gauss-Seidel passes settle it without residual motion. Keyed by (body, collider index,
    sample), so contacts that persist from one substep to the next find theirs.

    It is state beside the bodies': a scene that saves and restores its bodies should save
    and restore this too (`state()` / `restore()`), or `clear()` it, for bit-identical runs."""

    def __init__(self):
        self.clear()

    def clear(self):
        self.keys = np.zeros(0, dtype=np.int64)  # ascending
        self.impulses = np.zeros((0, 4))  # normal impulse (N s), friction impulse (3, world)

    def state(self) -> dict:
        return {"keys": self.keys.copy(), "impulses": self.impulses.copy()}

    def restore(self, state: dict):
        self.keys, self.impulses = state["keys"].copy(), state["impulses"].copy()

    def lookup(self, keys: np.ndarray) -> np.ndarray:
        """The stored impulses of `keys` ((K, 4); zeros where a contact is new)."""
        out = np.zeros((len(keys), 4))
        if len(self.keys):
            where = np.minimum(np.searchsorted(self.keys, keys), len(self.keys) - 1)
            found = self.keys[where] == keys
            out[found] = self.impulses[where[found]]
        return out


def contact_keys(body, collider, sample):
    """Keys of contacts that stay the same from one substep to the next, ascending in slot
    order: body, then collider index, then the sample's index in the body (each below 2**20)."""
    return (body.astype(np.int64) << 40) | (collider.astype(np.int64) << 20) | sample.astype(np.int64)


def resolve_contacts(store, table, gravity, dt: float, cache: ContactCache = None) -> int:
    """Contacts of every body of `store` (bodies.store.BodyStore) against every other collider
    of `table` (scene.colliders.ColliderTable: static, kinematic and the other bodies'
    entries) over one substep of dt seconds, gravity (3,) in m/s^2. Adds g dt to every
    body's velocity, resolves the contacts into store.v and store.L, and moves store.x and
    store.R out of penetration. Returns the number of contacts (speculative ones included).

    cache: a ContactCache kept from substep to substep turns warm starting on (None: every
    solve starts from zero impulses, and the result depends on the bodies' state only)."""
    dt = float(dt)
    if not dt > 0.0:
        raise ValueError(f"dt must be > 0; got {dt}")
    gravity = np.asarray(gravity, dtype=np.float64)
    if gravity.shape != (3,) or not np.all(np.isfinite(gravity)):
        raise ValueError(f"gravity must be 3 finite numbers (m/s^2); got {gravity.tolist()}")
    if store.count == 0:
        return 0
    store.v += gravity * dt  # phase 1
    bodies = _body_rows(store)
    bounce_speed = max(BOUNCE_FACTOR * float(np.linalg.norm(gravity)) * dt, BOUNCE_FLOOR)
    slots, samples, sample_body, owner_of_entry = _broad_phase(store, table, bodies, dt)
    if len(slots) == 0:
        if cache is not None:
            cache.clear()
        return 0
    dtype = runtime.float_dtype()
    found = np.empty((len(slots), FOUND_COLUMNS), dtype=dtype)
    _detect(colliders=table.args, groups=table.groups, samples=samples.astype(dtype), slots=slots, dt=dt,
            margin=MARGIN, slack=bounce_speed, found=found)
    contacts, pairs, keys = _gather(store, table, slots, samples, sample_body, owner_of_entry, found)
    if cache is not None:
        contacts[:, 15:19] = cache.lookup(keys)
    if len(contacts) == 0:
        if cache is not None:
            cache.clear()
        return 0
    work = _solve_rows(store, contacts, pairs, dt, bounce_speed)
    if np.any(gravity):
        store.supported = supported_bodies(store.count, contacts[:, 0:3], pairs, work[:, 10], -gravity)
    if cache is not None:
        cache.keys = keys
        cache.impulses = np.column_stack([work[:, 10], work[:, 11:12] * work[:, 0:3] + work[:, 12:13] * work[:, 3:6]])
    return len(contacts)


def supported_bodies(count, normals, pairs, normal_impulses, up) -> np.ndarray:
    """Which bodies rest on something that holds them (docs/physics.md 7.2): a contact pushing
    up (normal within acos(SUPPORT_COS) of `up`) with a collider, or with a body that rests
    so, found level by level. Particles lying on such a body meet it as immovable."""
    up = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    pushing = (normal_impulses > 0.0) & (normals.astype(np.float64) @ up > SUPPORT_COS)
    supported = np.zeros(count, dtype=bool)
    for _ in range(count):
        below_held = (pairs[:, 1] < 0) | supported[np.maximum(pairs[:, 1], 0)]
        now = supported.copy()
        now[pairs[pushing & below_held, 0]] = True
        if np.array_equal(now, supported):
            break
        supported = now
    return supported


def resolve_held(store, held, dt: float) -> int:
    """Shock propagation for bodies lying on particles (docs/physics.md 7.2): the contacts
    `held` (coupling.Coupling.collect: body, point, the body's outward normal there, depth)
    of particles held by what they rest on, as immovable contacts of the bodies, solved like
    their other contacts (no restitution: the impact was exchanged with the particles while
    they were free): the body stops on them all at once, penetration goes by positions.
    Returns the number of contacts."""
    if not len(held):
        return 0
    body, point, normal, depth = held
    friction = np.array([m.friction for m in store.materials])[body]
    count = len(body)
    contacts = np.zeros((count, CONTACT_COLUMNS))
    contacts[:, 0:3] = -normal  # (pointing from the particle into the body)
    contacts[:, 3:6] = point - store.x[body]
    contacts[:, 12] = -depth
    contacts[:, 14] = friction
    pairs = np.ascontiguousarray(np.column_stack([body, np.full(count, -1)]), dtype=np.int32)
    _solve_rows(store, contacts, pairs, dt, 0.0)
    return count


def _solve_rows(store, contacts, pairs, dt, bounce_speed):
    """Phases 5 and 6 over given contact rows, into the store; returns the work rows."""
    dtype = runtime.float_dtype()
    work = np.zeros((len(contacts), WORK_COLUMNS), dtype=dtype)
    totals = np.zeros((store.count, TOTAL_COLUMNS), dtype=dtype)
    _solve(contacts=np.ascontiguousarray(contacts, dtype=dtype), pairs=pairs, bodies=_body_rows(store).astype(dtype),
           dt=dt, bounce_speed=bounce_speed, iterations=VELOCITY_ITERATIONS, position_iterations=POSITION_ITERATIONS,
           correction=CORRECTION, slop=SLOP, max_push=MAX_PUSH_SPEED, work=work, totals=totals)
    _apply(store, totals.astype(np.float64), dt)
    return work


# ---------------------------------------------------------------------------- host phases
def _body_rows(store) -> np.ndarray:
    """One row per body: v, w, 1/m and the world inverse inertia R I^-1 R^T (float64)."""
    rows = np.zeros((store.count, BODY_COLUMNS))
    for b in range(store.count):
        inv_inertia = store.inv_inertia_world(b)
        rows[b, 0:3] = store.v[b]
        rows[b, 3:6] = inv_inertia @ store.L[b]
        rows[b, 6] = store.inv_mass(b)
        rows[b, 7:16] = inv_inertia.ravel()
    return rows


def _broad_phase(store, table, bodies, dt):
    """Phase 2. Returns the slots ((K, 2) int32: sample, collider index), the samples
    ((S, SAMPLE_COLUMNS) float64, world), each sample's body, and each table entry's body
    (-1 for a collider that is no body). Slots run body by body, collider by collider,
    sample by sample: a fixed order, so the contacts keep it."""
    entries = table.entries
    index_of = {id(e): i for i, e in enumerate(entries)}
    owner_of_entry = np.full(len(entries), -1, dtype=np.int32)
    own_entry = np.empty(store.count, dtype=np.int64)
    for b, entry in enumerate(store.entries):
        if id(entry) not in index_of:
            raise ValueError(f"body {b}'s collider entry is not in the collider table")
        own_entry[b] = index_of[id(entry)]
        owner_of_entry[own_entry[b]] = b
    centers = np.array([e.center for e in entries], dtype=np.float64)
    bounds = np.array([e.shape.params[3] for e in entries], dtype=np.float64)
    speeds = np.array([np.linalg.norm(e.velocity) + np.linalg.norm(e.angular_velocity) * min(e.shape.params[3], 1e15)
                       for e in entries])
    blocks, slot_blocks, sample_body, offset = [], [], [], 0
    for b in range(store.count):
        points, radii = surface_samples(store.entries[b].shape)
        center, rotation = store.shape_pose(b)
        world = points @ rotation.T + center
        velocity = bodies[b, 0:3] + np.cross(bodies[b, 3:6], world - store.x[b])
        blocks.append(np.column_stack([world, radii, velocity]))
        sample_body.append(np.full(len(points), b, dtype=np.int32))
        ci = own_entry[b]
        speed = np.linalg.norm(bodies[b, 0:3]) + np.linalg.norm(bodies[b, 3:6]) * bounds[ci]
        reach = bounds[ci] + bounds + MARGIN + dt * (speed + speeds) + 1e-9
        near = np.linalg.norm(centers - centers[ci], axis=1) <= reach
        near[ci] = False
        ids = np.arange(offset, offset + len(points), dtype=np.int32)
        for cj in np.flatnonzero(near):
            slot_blocks.append(np.column_stack([ids, np.full(len(ids), cj, dtype=np.int32)]))
        offset += len(points)
    slots = np.concatenate(slot_blocks) if slot_blocks else np.zeros((0, 2), dtype=np.int32)
    return (np.ascontiguousarray(slots, dtype=np.int32), np.concatenate(blocks), np.concatenate(sample_body),
            owner_of_entry)


def _gather(store, table, slots, samples, sample_body, owner_of_entry, found):
    """Phase 4: the slots holding a contact, in slot order, as the solve's rows ((C,
    CONTACT_COLUMNS) float64, warm-start impulses zero), body pairs ((C, 2) int32: the
    sample's body, the other body or -1 for a static or kinematic collider) and their
    keys (contact_keys)."""
    hit = np.flatnonzero(found[:, 0] < 0.5 * INFINITY)
    if len(hit) == 0:
        return np.zeros((0, CONTACT_COLUMNS)), np.zeros((0, 2), dtype=np.int32), np.zeros(0, dtype=np.int64)
    sample, collider = slots[hit, 0], slots[hit, 1]
    gap = found[hit, 0].astype(np.float64)
    normal = found[hit, 1:4].astype(np.float64)
    a = sample_body[sample]
    other = owner_of_entry[collider]
    x = samples[sample, 0:3]
    radius = samples[sample, 3]
    point = x - (radius + 0.5 * gap)[:, None] * normal  # midway between the two surfaces
    arm_a = point - store.x[a]
    arm_b = np.where((other >= 0)[:, None], point - store.x[np.maximum(other, 0)], 0.0)
    surface = np.where((other >= 0)[:, None], 0.0, found[hit, 4:7].astype(np.float64))
    body_e = np.array([m.restitution for m in store.materials])
    body_mu = np.array([m.friction for m in store.materials])
    entry_e = np.array([e.material.restitution for e in table.entries])
    entry_mu = np.array([e.material.friction for e in table.entries])
    restitution = np.maximum(body_e[a], entry_e[collider])  # combined_material, vectorised
    friction = np.sqrt(body_mu[a] * entry_mu[collider])
    warm = np.zeros((len(hit), 4))
    contacts = np.column_stack([normal, arm_a, arm_b, surface, gap, restitution, friction, warm])
    pairs = np.ascontiguousarray(np.column_stack([a, other]), dtype=np.int32)
    first = np.searchsorted(sample_body, np.arange(store.count))  # each body's first sample
    keys = contact_keys(a, collider, sample - first[a])
    return np.ascontiguousarray(contacts), pairs, keys


def _apply(store, totals, dt):
    """Phase 5 and 6 results into the store: v += P / m, L += sum of r x P (both float64),
    and the pseudo-velocities' motion over dt into x and R."""
    for b in range(store.count):
        if np.any(totals[b, 0:6]):
            store.v[b] = store.v[b] + totals[b, 0:3] * store.inv_mass(b)
            store.L[b] = store.L[b] + totals[b, 3:6]
        if np.any(totals[b, 6:9]):
            store.x[b] = store.x[b] + dt * totals[b, 6:9]
        if np.any(totals[b, 9:12]):
            store.R[b] = orthonormal(rotation_from_vector(dt * totals[b, 9:12]) @ store.R[b])


# ---------------------------------------------------------------------------- kernels
@ti.kernel
def _detect(colliders: ColliderArgs, groups: ti.template(), samples: ti.types.ndarray(), slots: ti.types.ndarray(),
            dt: float, margin: float, slack: float,
            # outputs
            found: ti.types.ndarray()):
    """Phase 3: per slot (sample s, collider ci), the gap phi - r to the collider at its start
    pose, its outward normal and its surface velocity at the contact point; gap INFINITY
    when the sample is beyond reach, margin + dt (|v - v_s| + slack) (docs/physics.md 1.3:
    the distance is exact within the reach it is asked for)."""
    for k in range(slots.shape[0]):
        s = slots[k, 0]
        ci = slots[k, 1]
        x = vec3(samples[s, 0], samples[s, 1], samples[s, 2])
        r = samples[s, 3]
        v = vec3(samples[s, 4], samples[s, 5], samples[s, 6])
        center = colliders.center0[ci]
        rotation = colliders.rotation0[ci]
        vs = colliders.velocity[ci] + colliders.angular_velocity[ci].cross(x - center)
        reach = margin + dt * ((v - vs).norm() + slack)
        found[k, 0] = INFINITY
        if (x - center).norm() - colliders.params[ci][3] - r <= reach:
            phi, n = world_sdf(colliders, groups, ci, colliders.kind[ci], colliders.params[ci], center, rotation, x,
                               r + reach)
            gap = phi - r
            if gap <= reach:
                point = x - (r + 0.5 * gap) * n
                vp = colliders.velocity[ci] + colliders.angular_velocity[ci].cross(point - center)
                found[k, 0] = gap
                for a in ti.static(range(3)):
                    found[k, 1 + a] = n[a]
                    found[k, 4 + a] = vp[a]


@ti.func
def _row3(a: ti.template(), i, col):
    return vec3(a[i, col], a[i, col + 1], a[i, col + 2])


@ti.func
def _set3(a: ti.template(), i, col, value):
    for j in ti.static(range(3)):
        a[i, col + j] = value[j]


@ti.func
def _inv_inertia(bodies: ti.template(), b):
    return ti.Matrix([[bodies[b, 7 + 3 * i + j] for j in ti.static(range(3))] for i in ti.static(range(3))])


@ti.func
def _velocity_at(bodies: ti.template(), totals: ti.template(), b, arm, pseudo: ti.template()):
    """Velocity (or pseudo-velocity) of body b's material point at arm from its centre of mass."""
    out = vec3(0.0, 0.0, 0.0)
    if ti.static(pseudo):
        out = _row3(totals, b, 6) + _row3(totals, b, 9).cross(arm)
    else:
        out = _row3(bodies, b, 0) + _row3(bodies, b, 3).cross(arm)
    return out


@ti.func
def _relative_velocity(contacts: ti.template(), pairs: ti.template(), bodies: ti.template(), totals: ti.template(),
                       k, pseudo: ti.template()):
    """v_a - v_b at contact k (b: the other body, or the collider's surface velocity)."""
    a = pairs[k, 0]
    b = pairs[k, 1]
    rel = _velocity_at(bodies, totals, a, _row3(contacts, k, 3), pseudo)
    if b >= 0:
        rel -= _velocity_at(bodies, totals, b, _row3(contacts, k, 6), pseudo)
    else:
        if ti.static(not pseudo):  # (pseudo-velocities: colliders do not take part)
            rel -= _row3(contacts, k, 9)
    return rel


@ti.func
def _push(contacts: ti.template(), pairs: ti.template(), bodies: ti.template(), totals: ti.template(), k,
          impulse: vec3, pseudo: ti.template()):
    """Apply +impulse to the sample's body and -impulse to the other one (docs/physics.md 2,
    "Two movable bodies"): velocities change by J / m and I^-1 (r x J); the totals keep the
    impulses themselves (or the pseudo-velocities)."""
    for side in ti.static(range(2)):
        b = pairs[k, side]
        if b >= 0:
            j = impulse if side == 0 else -impulse
            arm = _row3(contacts, k, 3 + 3 * side)
            dv = bodies[b, 6] * j
            dw = _inv_inertia(bodies, b) @ arm.cross(j)
            if ti.static(pseudo):
                _set3(totals, b, 6, _row3(totals, b, 6) + dv)
                _set3(totals, b, 9, _row3(totals, b, 9) + dw)
            else:
                _set3(bodies, b, 0, _row3(bodies, b, 0) + dv)
                _set3(bodies, b, 3, _row3(bodies, b, 3) + dw)
                _set3(totals, b, 0, _row3(totals, b, 0) + j)
                _set3(totals, b, 3, _row3(totals, b, 3) + arm.cross(j))


@ti.func
def _effective_mass(contacts: ti.template(), pairs: ti.template(), bodies: ti.template(), k, d: vec3):
    """1 / (d . dv_rel per unit impulse along d): 1/m_a + (r_a x d) . I_a^-1 (r_a x d) + same for b."""
    inverse = 0.0
    for side in ti.static(range(2)):
        b = pairs[k, side]
        if b >= 0:
            rd = _row3(contacts, k, 3 + 3 * side).cross(d)
            inverse += bodies[b, 6] + rd.dot(_inv_inertia(bodies, b) @ rd)
    return 1.0 / inverse if inverse > 0.0 else 0.0


@ti.func
def _normal_step(contacts: ti.template(), pairs: ti.template(), bodies: ti.template(), totals: ti.template(),
                 work: ti.template(), k, target: ti.template(), accumulated: ti.template(), pseudo: ti.template()):
    """One Gauss-Seidel step of contact k's normal constraint, v_n >= work[k, target], on the
    velocities or (pseudo) the pseudo-velocities: the accumulated impulse in work[k,
    accumulated] kept >= 0, the change applied. Returns the new accumulated impulse."""
    n = _row3(contacts, k, 0)
    vn = _relative_velocity(contacts, pairs, bodies, totals, k, pseudo).dot(n)
    total = ti.max(work[k, accumulated] - work[k, 6] * (vn - work[k, target]), 0.0)
    _push(contacts, pairs, bodies, totals, k, (total - work[k, accumulated]) * n, pseudo)
    work[k, accumulated] = total
    return total


@ti.kernel
def _solve(contacts: ti.types.ndarray(), pairs: ti.types.ndarray(), bodies: ti.types.ndarray(), dt: float,
           bounce_speed: float, iterations: ti.i32, position_iterations: ti.i32, correction: float, slop: float,
           max_push: float,
           # outputs (bodies' v and w columns are the solve's working velocities)
           work: ti.types.ndarray(), totals: ti.types.ndarray()):
    """Phases 5 and 6, serial: sequential impulses over the contacts in their fixed order."""
    ti.loop_config(serialize=True)
    for _ in range(1):
        # Preparation: tangent basis, effective masses, the normal velocity wanted.
        for k in range(contacts.shape[0]):
            n = _row3(contacts, k, 0)
            t1 = n.cross(vec3(1.0, 0.0, 0.0))
            if ti.abs(n.x) > 0.57735:
                t1 = n.cross(vec3(0.0, 1.0, 0.0))
            t1 = t1.normalized()
            t2 = n.cross(t1)
            _set3(work, k, 0, t1)
            _set3(work, k, 3, t2)
            work[k, 6] = _effective_mass(contacts, pairs, bodies, k, n)
            work[k, 7] = _effective_mass(contacts, pairs, bodies, k, t1)
            work[k, 8] = _effective_mass(contacts, pairs, bodies, k, t2)
            gap = contacts[k, 12]
            restitution = contacts[k, 13]
            vn = _relative_velocity(contacts, pairs, bodies, totals, k, False).dot(n)
            # Speculative contact: v_n >= -gap / dt closes the gap within the substep, no
            # more; a touching or penetrating one holds (v_n >= 0; the position pass pushes).
            target = -ti.max(gap, 0.0) / dt
            # Restitution (docs/physics.md 2, step 2) where the approach reaches the surface
            # within this substep faster than a resting contact's: -e v_n from the velocity
            # before the solve.
            if restitution > 0.0 and vn < -bounce_speed and gap + vn * dt < 0.0:
                target = -restitution * vn
            work[k, 9] = target
            # Position correction: push out a fraction of the depth beyond the slop.
            work[k, 13] = ti.min(correction * (-gap - slop) / dt, max_push)
        # Warm start (after every target is set from the velocities before the solve): the
        # impulses the contacts ended the last substep with, friction within its disc.
        for k in range(contacts.shape[0]):
            normal_impulse = contacts[k, 15]
            if normal_impulse > 0.0:
                friction = _row3(contacts, k, 16)
                f1 = friction.dot(_row3(work, k, 0))
                f2 = friction.dot(_row3(work, k, 3))
                limit = contacts[k, 14] * normal_impulse
                size = ti.sqrt(f1 * f1 + f2 * f2)
                if size > limit:
                    f1 *= limit / size
                    f2 *= limit / size
                impulse = normal_impulse * _row3(contacts, k, 0) + f1 * _row3(work, k, 0) + f2 * _row3(work, k, 3)
                _push(contacts, pairs, bodies, totals, k, impulse, False)
                work[k, 10] = normal_impulse
                work[k, 11] = f1
                work[k, 12] = f2
        # Velocities: Gauss-Seidel with accumulated impulses (normal >= 0; friction within
        # the Coulomb disc mu * normal impulse, docs/physics.md 2, step 3).
        for _it in range(iterations):
            for k in range(contacts.shape[0]):
                total = _normal_step(contacts, pairs, bodies, totals, work, k, 9, 10, False)
                t1 = _row3(work, k, 0)
                t2 = _row3(work, k, 3)
                rel = _relative_velocity(contacts, pairs, bodies, totals, k, False)
                f1 = work[k, 11] - work[k, 7] * rel.dot(t1)
                f2 = work[k, 12] - work[k, 8] * rel.dot(t2)
                limit = contacts[k, 14] * total
                size = ti.sqrt(f1 * f1 + f2 * f2)
                if size > limit:
                    scale = limit / size
                    f1 *= scale
                    f2 *= scale
                _push(contacts, pairs, bodies, totals, k, (f1 - work[k, 11]) * t1 + (f2 - work[k, 12]) * t2, False)
                work[k, 11] = f1
                work[k, 12] = f2
        # Positions: the same iteration on pseudo-velocities, which move the pose only.
        for _it in range(position_iterations):
            for k in range(contacts.shape[0]):
                _normal_step(contacts, pairs, bodies, totals, work, k, 13, 14, True)
