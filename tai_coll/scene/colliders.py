"""The collider table: what the step kernels see of every collider in a scene.

Kernels never hold Python collider objects. They loop over this table (one array per
attribute, handed to kernels as one argument pack: `args`, types.ColliderArgs) and dispatch
on `kind`. Each collider has two poses, at the start (t) and end (t + dt) of the current
substep: interference is tested at the end pose (docs/physics.md 3, moving objects),
"already penetrating" at the start pose.
"""


from dataclasses import dataclass

import numpy as np
import taichi as ti

from .. import notices, runtime
from ..geometry import kinds
from ..geometry.colliders import Collider
from ..materials import Material
from ..types import ColliderArgs


#: The most a kinematic collider may turn in one substep (rad) before the scene warns.
#: Contacts with it are found along straight paths relative to it and take its surface
#: velocity from the substep's mean rates: a particle struck by a turning arm leaves within
#: 1.5 % of the arm's surface speed at 0.3 rad a substep, 6 % at 0.5 rad, 20 % at 1 rad
#: (measured, tests/test_fast_paddle.py), and a turn past about 1.5 rad can miss it.
MAX_TURN = 0.3


@dataclass
class ColliderEntry:
    """A collider placed in a scene: shape, material, motion and its current pose."""

    shape: Collider
    material: Material
    motion: object  # None (static), ConstantMotion or CallableMotion
    center: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    repulsion: object = None  # a RepulsionField, read by the penalty solver

    @property
    def is_kinematic(self) -> bool:
        return self.motion is not None


class ColliderTable:
    def __init__(self, capacity: int = 8):
        self.entries: list[ColliderEntry] = []
        self.capacity = 0
        self.version = 0  # counts uploads: colliders added, moved or changed
        self._warned_turn = set()  # ids of the entries warned about turning too far in a substep
        self._args = None  # the argument pack, built when first asked for (see `args`)
        self._allocate(capacity)

    def _allocate(self, capacity):
        self.kind = ti.ndarray(ti.i32, shape=capacity)
        self.params = ti.Vector.ndarray(4, float, shape=capacity)
        self.material = ti.Vector.ndarray(3, float, shape=capacity)  # restitution, friction, wet_friction
        self.center0 = ti.Vector.ndarray(3, float, shape=capacity)
        self.rotation0 = ti.Matrix.ndarray(3, 3, float, shape=capacity)
        self.center1 = ti.Vector.ndarray(3, float, shape=capacity)
        self.rotation1 = ti.Matrix.ndarray(3, 3, float, shape=capacity)
        self.velocity = ti.Vector.ndarray(3, float, shape=capacity)
        self.angular_velocity = ti.Vector.ndarray(3, float, shape=capacity)
        self.ishape = ti.Vector.ndarray(8, ti.i32, shape=capacity)
        self.fshape = ti.Vector.ndarray(8, float, shape=capacity)
        self.fpool = ti.ndarray(float, shape=1)
        self.ipool = ti.ndarray(ti.i32, shape=1)
        # rigid bodies (bodies/coupling.py fills these; every entry -1 while there are none)
        self.body = ti.ndarray(ti.i32, shape=capacity)
        self.body.fill(-1)
        self.body_inv_mass = ti.ndarray(float, shape=capacity)
        self.body_inv_inertia = ti.Matrix.ndarray(3, 3, float, shape=capacity)
        self.body_com = ti.Vector.ndarray(3, float, shape=capacity)
        self.body_up = ti.Vector.ndarray(3, float, shape=capacity)
        if not hasattr(self, "support"):
            self.support = ti.ndarray(ti.i32, shape=1)
            self.support_up = ti.Vector.ndarray(3, float, shape=1)
            self.support_up.fill(0.0)
        if not hasattr(self, "ledger_body"):
            self.set_ledger(ti.ndarray(ti.i32, shape=1), ti.Vector.ndarray(3, float, shape=1),
                            ti.Vector.ndarray(3, float, shape=1), ti.Vector.ndarray(3, float, shape=1))
        self.capacity = capacity
        self._args = None

    def set_support(self, levels, up):
        """Particles' support levels (shock.py) and the up direction: against a body above it,
        a particle held by its supports is immovable (docs/physics.md 7.2); up None: off."""
        if levels is not None and levels is not self.support:
            self.support = levels
            self._args = None
        self.support_up.from_numpy(np.zeros((1, 3), dtype=runtime.float_dtype()) if up is None else
                                   np.asarray(up, dtype=runtime.float_dtype()).reshape(1, 3))

    @property
    def has_bodies(self) -> bool:
        return any(getattr(e.motion, "is_body", False) for e in self.entries)

    def set_ledger(self, ledger_body, ledger_impulse, ledger_torque, body_total):
        """The per-particle ledger of impulses given to bodies (bodies/coupling.py) that the
        table's argument pack carries to the particle kernels."""
        self.ledger_body, self.ledger_impulse, self.ledger_torque = ledger_body, ledger_impulse, ledger_torque
        self.body_total = body_total
        self._args = None

    @property
    def args(self) -> ColliderArgs:
        """The table as kernels take it (types.ColliderArgs), rebuilt only when its arrays or
        its count change."""
        if self._args is None:
            self._args = ColliderArgs(count=len(self.entries), kind=self.kind, params=self.params,
                                      material=self.material, center0=self.center0, rotation0=self.rotation0,
                                      center1=self.center1, rotation1=self.rotation1, velocity=self.velocity,
                                      angular_velocity=self.angular_velocity, ishape=self.ishape, fshape=self.fshape,
                                      fpool=self.fpool, ipool=self.ipool, body=self.body,
                                      body_inv_mass=self.body_inv_mass, body_inv_inertia=self.body_inv_inertia,
                                      body_com=self.body_com, body_up=self.body_up, ledger_body=self.ledger_body,
                                      ledger_impulse=self.ledger_impulse, ledger_torque=self.ledger_torque,
                                      body_total=self.body_total, support=self.support,
                                      support_up=self.support_up)
        return self._args

    def __len__(self):
        return len(self.entries)

    @property
    def groups(self) -> int:
        """Compile-time mask of the collider kind groups present (geometry.kinds)."""
        return kinds.groups_of(e.shape.kind for e in self.entries)

    @property
    def has_kinematic(self) -> bool:
        return any(e.is_kinematic for e in self.entries)

    def add(self, shape: Collider, material: Material, motion, time: float) -> ColliderEntry:
        entry = ColliderEntry(shape, material, motion, shape.center.copy(), shape.rotation.copy(),
                              np.zeros(3), np.zeros(3))
        if motion is not None:
            entry.center, entry.rotation = motion.pose(shape.center, shape.rotation, time)
            if hasattr(motion, "velocity"):
                entry.velocity, entry.angular_velocity = motion.velocity, motion.angular_velocity
        self.entries.append(entry)
        self._args = None
        if len(self.entries) > self.capacity:
            self._allocate(2 * self.capacity)
        self.upload_all()
        return entry

    def advance(self, t0: float, dt: float):
        """Set the substep's start and end poses of kinematic colliders for [t0, t0 + dt]."""
        poses0, poses1 = [], []
        for e in self.entries:
            if e.motion is None:
                pose0 = pose1 = (e.center, e.rotation)
            else:
                pose0 = (e.center, e.rotation)
                pose1 = e.motion.pose(e.shape.center, e.shape.rotation, t0 + dt)
                e.velocity, e.angular_velocity = e.motion.rates(pose0, pose1, dt)
                e.center, e.rotation = pose1
                self._check_turn(e, dt)
            poses0.append(pose0)
            poses1.append(pose1)
        self._poses = (poses0, poses1)
        self._upload_poses(poses0, poses1)

    def replace_poses(self, rows: dict):
        """Replace the substep's (start, end) poses of some entries, {id(entry): (pose0, pose1)}
        (rigid bodies: their predicted motion, bodies/system.py), after `advance`."""
        poses0, poses1 = (list(p) for p in self._poses)
        for k, e in enumerate(self.entries):
            if id(e) in rows:
                poses0[k], poses1[k] = rows[id(e)]
        self._poses = (poses0, poses1)
        self._upload_poses(poses0, poses1)

    def commit_poses(self):
        """Every entry at its current pose, start and end (after a substep moved bodies)."""
        poses = [(e.center, e.rotation) for e in self.entries]
        self._poses = (poses, poses)
        self._upload_poses(poses, poses)

    def _check_turn(self, entry: ColliderEntry, dt: float):
        """Warn once per collider that turns more than MAX_TURN in a substep."""
        speed = float(np.linalg.norm(entry.angular_velocity))
        if speed * dt > MAX_TURN and id(entry) not in self._warned_turn:
            self._warned_turn.add(id(entry))
            index = self.entries.index(entry)
            notices.warn(
                f"collider {index} ({type(entry.shape).__name__}) turns {speed * dt:.3g} rad in a substep of dt = "
                f"{dt:.3g} s (angular speed {speed:.4g} rad/s). Contacts with a moving collider are found along "
                "straight paths relative to it and get its surface velocity from its mean rates over the substep, "
                f"which beyond {MAX_TURN} rad a substep misjudge them by percents (and past about 1.5 rad can miss "
                "them): use dt <= "
                f"{MAX_TURN / speed:.3g} s", RuntimeWarning)

    def upload_all(self):
        self.version += 1
        n = len(self.entries)
        dtype = runtime.float_dtype()
        cap = self.capacity
        kind = np.zeros(cap, dtype=np.int32)
        params = np.zeros((cap, 4), dtype=dtype)
        material = np.zeros((cap, 3), dtype=dtype)
        kind[:n] = [e.shape.kind for e in self.entries]
        params[:n] = [e.shape.params for e in self.entries]
        material[:n] = [(e.material.restitution, e.material.friction, e.material.wet_friction)
                        for e in self.entries]
        self.kind.from_numpy(kind)
        self.params.from_numpy(params)
        self.material.from_numpy(material)
        self._upload_shape_data()
        poses = [(e.center, e.rotation) for e in self.entries]
        self._poses = (poses, poses)
        self._upload_poses(poses, poses)

    def _upload_shape_data(self):
        """Pack every collider's array block into the float and int pools (offsets in
        ishape[0] and ishape[1])."""
        dtype = runtime.float_dtype()
        ishape = np.zeros((self.capacity, 8), dtype=np.int32)
        fshape = np.zeros((self.capacity, 8), dtype=dtype)
        fblocks, iblocks = [np.zeros(1, dtype=dtype)], [np.zeros(1, dtype=np.int32)]
        f_used, i_used = 1, 1  # slot 0 of each pool stays unused, so empty pools are never zero-sized
        for k, e in enumerate(self.entries):
            meta_i, meta_f, fdata, idata = e.shape.shape_data()
            ishape[k] = meta_i
            fshape[k] = meta_f
            ishape[k, 0], ishape[k, 1] = f_used, i_used
            fblocks.append(np.asarray(fdata, dtype=dtype))
            iblocks.append(np.asarray(idata, dtype=np.int32))
            f_used += len(fdata)
            i_used += len(idata)
        self.ishape.from_numpy(ishape)
        self.fshape.from_numpy(fshape)
        if self.fpool.shape[0] != f_used:
            self.fpool = ti.ndarray(float, shape=f_used)
            self._args = None
        if self.ipool.shape[0] != i_used:
            self.ipool = ti.ndarray(ti.i32, shape=i_used)
            self._args = None
        self.fpool.from_numpy(np.concatenate(fblocks))
        self.ipool.from_numpy(np.concatenate(iblocks))

    def _upload_poses(self, poses0, poses1):
        """One packed host array and one small kernel: this runs every substep of a scene
        with moving colliders, where six separate transfers cost more than the step."""
        self.version += 1
        n = len(self.entries)
        if n == 0:
            return
        packed = np.empty((n, POSE_WIDTH), dtype=runtime.float_dtype())
        for i, (e, (c0, R0), (c1, R1)) in enumerate(zip(self.entries, poses0, poses1)):
            packed[i, 0:3] = c0
            packed[i, 3:12] = R0.ravel()
            packed[i, 12:15] = c1
            packed[i, 15:24] = R1.ravel()
            packed[i, 24:27] = e.velocity
            packed[i, 27:30] = e.angular_velocity
        _scatter_poses(packed, self.center0, self.rotation0, self.center1, self.rotation1, self.velocity,
                       self.angular_velocity)


POSE_WIDTH = 30


@ti.kernel
def _scatter_poses(packed: ti.types.ndarray(), center0: ti.types.ndarray(), rotation0: ti.types.ndarray(),
                   center1: ti.types.ndarray(), rotation1: ti.types.ndarray(), velocity: ti.types.ndarray(),
                   angular_velocity: ti.types.ndarray()):
    for i in range(packed.shape[0]):
        for a in ti.static(range(3)):
            center0[i][a] = packed[i, a]
            center1[i][a] = packed[i, 12 + a]
            velocity[i][a] = packed[i, 24 + a]
            angular_velocity[i][a] = packed[i, 27 + a]
            for b in ti.static(range(3)):
                rotation0[i][a, b] = packed[i, 3 + 3 * a + b]
                rotation1[i][a, b] = packed[i, 15 + 3 * a + b]
