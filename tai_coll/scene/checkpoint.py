"""A scene's state on disk: `save_state` / `load_state` (checkpoint and resume), and the
frame that exporters write (`frame_data`).

A state is everything the next step reads, so that a scene built by the same script, loaded
with it, continues bit for bit as the run that saved it would have (on the CPU, where the
kernels' order of work is fixed): the particle store in its storage order (every per-slot
array: positions, velocities, spins, flags, allowances, rest times, clearances, separating
planes, ids), the pair solver's kept arrays (the hash grid, Verlet lists, tangential springs,
support levels, its counters and keys), the rigid bodies and their contact caches, the colliders' poses, the
emitters' random generators and counters, the sinks' count, time, dt, the frame count and the
scene's warnings given. The colliders, bodies' shapes and masses, emitters, sinks, solver and
settings themselves are the script's: they are not saved but compared (`fingerprint`), and a
state is refused when they differ.

The file is a versioned `.npz` (FORMAT, VERSION): named arrays, and one JSON document
(META_KEY) describing the scalars, which array each attribute is and the fingerprint. The
containers' attributes are saved as they are (`_Writer`), less the argument packs and work
arrays they rebuild (SKIP); Taichi arrays come back as new arrays of the same element type,
and arrays two attributes share stay shared.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import taichi as ti
from taichi.lang._ndarray import Ndarray

from .. import export, runtime
from ..types import new_ndarray

FORMAT = "tai_coll.state"
VERSION = 2  # 2: the particle store keeps separating planes (solvers/impulse.py)
META_KEY = "__meta__"

#: Attributes of each container left out of a state and reset to None on loading: argument
#: packs, host caches, work arrays rebuilt on demand.
RESET = {
    "store": {"_args", "_spin_args", "_slots_host", "_spare", "_w_spare", "_largest"},
    "pairs": {"_law", "_load_args", "_push_cap", "_calm", "redo"},
    "grid": {"_args", "_lists", "_bounds", "awake"},
    "lists": {"_args"},
    "springs": {"_packs"},
}
#: Attributes left out and left alone: the script's (settings, the runtime) and the
#: containers saved on their own (the pair solver's grid, lists and springs).
NOT_STATE = {"pairs": {"_runtime", "settings", "grid", "lists", "springs"}}
#: Everything a container's capture leaves out.
SKIP = {name: reset | NOT_STATE.get(name, set()) for name, reset in RESET.items()}
#: The collider table's rows for bodies, as the last substep uploaded them (the next substep
#: reads them before it uploads its own: the count of particles near each body).
TABLE_BODY_ROWS = ("body", "body_inv_mass", "body_inv_inertia", "body_com", "body_up")
#: The scene's own attributes a state holds.
SCENE_FIELDS = ("dt", "substeps", "_time_base", "_substep_count", "_substep_limit", "_watch", "_limits",
                "_solver_checked", "_solver_warned", "_warned_dropped", "_warned_crushed", "_frame",
                "_placed_checked")

_NUMPY_TO_TI = {np.dtype(np.float32): ti.f32, np.dtype(np.float64): ti.f64, np.dtype(np.int32): ti.i32,
                np.dtype(np.int64): ti.i64}


# ----------------------------------------------------------------------------- values <-> JSON and arrays
class _Writer:
    """Turns attribute values into JSON and named arrays (Taichi arrays by identity: one
    array two attributes share is saved once and the second names the first)."""

    def __init__(self):
        self.arrays = {}
        self._seen = {}

    def encode(self, key: str, value):
        if value is None or isinstance(value, (bool, int, float, str)):
            return {"v": value}
        if isinstance(value, np.generic):
            return {"v": value.item()}
        if isinstance(value, Ndarray):
            dims = len(value.element_shape)
            if id(value) in self._seen:
                return {"alias": self._seen[id(value)], "el": dims}
            self._seen[id(value)] = key
            self.arrays[key] = value.to_numpy()
            return {"nd": key, "el": dims}
        if isinstance(value, np.ndarray):
            self.arrays[key] = value.copy()
            return {"np": key}
        if isinstance(value, ti.lang.matrix.Matrix):  # a Taichi vector held on the host (the grid's bits)
            values = value.to_numpy()
            return {"tivec": values.tolist(), "int": bool(np.issubdtype(values.dtype, np.integer))}
        if isinstance(value, (tuple, list)):
            kind = "tuple" if isinstance(value, tuple) else "list"
            return {kind: [self.encode(f"{key}.{i}", item) for i, item in enumerate(value)]}
        if isinstance(value, (set, frozenset)):
            return {"set": sorted(value)}
        if isinstance(value, dict) and all(isinstance(k, str) for k in value):
            return {"dict": {k: self.encode(f"{key}.{k}", item) for k, item in value.items()}}
        raise TypeError(f"save_state: {key} holds a {type(value).__name__}, which a state cannot hold")

    def capture(self, prefix: str, obj, skip=()) -> dict:
        return {name: self.encode(f"{prefix}.{name}", value) for name, value in vars(obj).items() if name not in skip}


class _Reader:
    """The inverse of _Writer over a loaded file's arrays."""

    def __init__(self, arrays):
        self.arrays = arrays
        self._made = {}

    def _taichi(self, key: str, dims: int):
        if key not in self._made:
            values = self.arrays[key]
            split = values.ndim - dims
            array = new_ndarray(_NUMPY_TO_TI[values.dtype], values.shape[split:], values.shape[:split])
            array.from_numpy(np.ascontiguousarray(values))
            self._made[key] = array
        return self._made[key]

    def decode(self, meta):
        kind = next(k for k in meta if k not in ("el", "int"))
        value = meta[kind]
        if kind == "v":
            return value
        if kind in ("nd", "alias"):
            return self._taichi(value, meta["el"])
        if kind == "np":
            return self.arrays[value].copy()
        if kind == "tivec":
            return (ti.math.ivec3 if meta["int"] else ti.math.vec3)(*value)
        if kind == "tuple":
            return tuple(self.decode(m) for m in value)
        if kind == "list":
            return [self.decode(m) for m in value]
        if kind == "set":
            return set(value)
        if kind == "dict":
            return {k: self.decode(m) for k, m in value.items()}
        raise ValueError(f"load_state: unknown entry {kind!r}")

    def restore(self, obj, meta: dict, reset=()):
        for name in reset:
            setattr(obj, name, None)
        for name, m in meta.items():
            setattr(obj, name, self.decode(m))


# ----------------------------------------------------------------------------- what must match
def _pose_text(center, rotation) -> str:
    return f"at {np.round(np.asarray(center, float), 9).tolist()} rotation {np.round(rotation, 9).tolist()}"


def _shape_text(shape) -> str:
    text = f"{shape!r} {_pose_text(shape.center, shape.rotation)}"
    vertices = getattr(shape, "vertices", None)
    if vertices is not None:  # meshes: their repr counts; the content decides
        text += " mesh " + hashlib.sha1(np.ascontiguousarray(vertices, np.float64).tobytes()).hexdigest()[:12]
    return text


def fingerprint(scene) -> dict:
    """What a state is only valid for, as text per item: the solver and its settings, the
    precision, the stepping, the domain, the colliders (shape, pose at rest, material,
    motion), the bodies (shape, mass, inertia, material), the emitters and the sinks."""
    colliders, bodies = [], []
    store = scene._bodies.store
    for entry in scene._colliders.entries:
        if getattr(entry.motion, "is_body", False):
            b = entry.motion.index
            bodies.append(f"{_shape_text(entry.shape)} mass {store.mass[b]:.12g} inertia "
                          f"{np.round(store.inertia[b], 12).tolist()} {entry.material!r}")
        else:
            motion = "static" if entry.motion is None else type(entry.motion).__name__
            if hasattr(entry.motion, "velocity"):
                motion += f" {entry.motion.velocity.tolist()} {entry.motion.angular_velocity.tolist()}"
            colliders.append(f"{_shape_text(entry.shape)} {entry.material!r} {motion}"
                             f"{' repulsion ' + repr(entry.repulsion) if entry.repulsion is not None else ''}")
    return {
        "precision": runtime.info().precision,
        "solver": repr(scene.solver),
        "particle collisions": repr(scene._pairs.settings) if scene._pairs is not None else "off",
        "stepping": repr(scene._stepping),
        "domain": repr(None if scene.domain is None else np.asarray(scene.domain).tolist()),
        "colliders": colliders,
        "bodies": bodies,
        "emitters": [repr(e) for e in scene._emitters],
        "sinks": [_shape_text(r) for r in scene._sinks.regions],
    }


def _differences(saved: dict, now: dict) -> list[str]:
    lines = []
    for key in sorted(set(saved) | set(now)):
        a, b = saved.get(key), now.get(key)
        if a == b:
            continue
        if isinstance(a, list) and isinstance(b, list):
            if len(a) != len(b):
                lines.append(f"{key}: the state has {len(a)}, this scene {len(b)}")
                continue
            k = next(i for i, (x, y) in enumerate(zip(a, b)) if x != y)
            lines.append(f"{key} [{k}]: the state's {a[k]}; this scene's {b[k]}")
        else:
            lines.append(f"{key}: the state's {a}; this scene's {b}")
    return lines


# ----------------------------------------------------------------------------- save and load
def _version() -> str:
    import tai_coll

    return tai_coll.__version__


def _path(path, *, must_exist: bool) -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path must be a str or os.PathLike; got {type(path).__name__}")
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise ValueError(f"path must end in .npz (a state is a versioned .npz); got {str(path)!r}")
    if must_exist and not path.is_file():
        raise FileNotFoundError(f"path: no state file at {str(path)!r}")
    return path


def save_state(scene, path) -> Path:
    path = _path(path, must_exist=False)
    w = _Writer()
    colliders = scene._colliders
    bodies = scene._bodies
    pairs = scene._pairs
    meta = {
        "format": FORMAT, "version": VERSION, "tai_coll": _version(),
        "fingerprint": fingerprint(scene),
        "scene": {name: w.encode(f"scene.{name}", getattr(scene, name)) for name in SCENE_FIELDS},
        "gravity": list(map(float, scene.gravity)),
        "store": w.capture("store", scene._particles, SKIP["store"]),
        "colliders": {
            "version": colliders.version,
            "poses": w.encode("colliders.poses", colliders._poses),
            "entries": [w.encode(f"colliders.entry{k}", (e.center, e.rotation, e.velocity, e.angular_velocity))
                        for k, e in enumerate(colliders.entries)],
            "warned_turn": [k for k, e in enumerate(colliders.entries) if id(e) in colliders._warned_turn],
            "body_rows": {name: w.encode(f"colliders.{name}", getattr(colliders, name).to_numpy())
                          for name in TABLE_BODY_ROWS},
        },
        "bodies": {
            "store": w.encode("bodies.store", dict(bodies.store.state(), supported=bodies.store.supported)),
            "contacts": int(bodies.contacts), "held": int(bodies.held),
            "held_contacts": w.encode("bodies.held_contacts", bodies._held),
            "contact_cache": w.encode("bodies.contact_cache", bodies.contact_cache.state()),
            "after_cache": w.encode("bodies.after_cache", bodies.after_cache.state()),
            "counts": w.encode("bodies.counts", bodies.coupling.counts),
            "warned_travel": bool(bodies._warned_travel),
        },
        "emitters": [w.encode(f"emitter{k}", e.state()) for k, e in enumerate(scene._emitters)],
        "removed": int(scene._sinks.removed),
    }
    if pairs is not None:
        meta["pairs"] = {
            "self": w.capture("pairs", pairs, SKIP["pairs"]),
            "grid": w.capture("grid", pairs.grid, SKIP["grid"]),
            "lists": w.capture("lists", pairs.lists, SKIP["lists"]),
            "springs": w.capture("springs", pairs.springs, SKIP["springs"]),
        }
    arrays = dict(w.arrays)
    arrays[META_KEY] = np.array(json.dumps(meta))

    def write(target):
        with open(target, "wb") as f:
            np.savez(f, **arrays)

    path.parent.mkdir(parents=True, exist_ok=True)
    export.atomic_write(path, write)
    return path


def read_state(path) -> tuple[dict, dict]:
    """(meta, arrays) of a state file, checked to be one this version reads."""
    path = _path(path, must_exist=True)
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        meta = json.loads(str(arrays.pop(META_KEY)))
    except (OSError, ValueError, KeyError) as error:
        raise ValueError(f"path: {str(path)!r} is not a tai_coll state ({error})") from None
    if meta.get("format") != FORMAT:
        raise ValueError(f"path: {str(path)!r} is not a tai_coll state")
    if meta.get("version") != VERSION:
        raise ValueError(f"path: {str(path)!r} is a state of format version {meta.get('version')} "
                         f"(tai_coll {meta.get('tai_coll')}); this tai_coll reads version {VERSION}")
    return meta, arrays


def load_state(scene, path):
    meta, arrays = read_state(path)
    differences = _differences(meta["fingerprint"], fingerprint(scene))
    if differences:
        raise ValueError(f"path: the state in {str(path)!r} was saved from a different scene; it can only be "
                         "loaded into a scene built the same way. What differs:\n  " + "\n  ".join(differences))
    r = _Reader(arrays)
    # the script's scene is replaced wholesale from here on (nothing above changed it)
    for name, m in meta["scene"].items():
        setattr(scene, name, r.decode(m))
    scene.gravity = meta["gravity"]  # (wakes particles: the store's rest times come next)
    r.restore(scene._particles, meta["store"], RESET["store"])
    colliders = scene._colliders
    for entry, m in zip(colliders.entries, meta["colliders"]["entries"]):
        entry.center, entry.rotation, entry.velocity, entry.angular_velocity = r.decode(m)
    poses0, poses1 = r.decode(meta["colliders"]["poses"])
    colliders._poses = (poses0, poses1)
    colliders._upload_poses(poses0, poses1)
    colliders.version = meta["colliders"]["version"]
    colliders._warned_turn = {id(colliders.entries[k]) for k in meta["colliders"]["warned_turn"]}
    for name, m in meta["colliders"]["body_rows"].items():
        getattr(colliders, name).from_numpy(r.decode(m))
    bodies = scene._bodies
    b = meta["bodies"]
    state = r.decode(b["store"])
    store = bodies.store
    store.x, store.R, store.v, store.L, store.supported = (state[k] for k in ("x", "R", "v", "L", "supported"))
    bodies.contacts, bodies.held = b["contacts"], b["held"]
    bodies._held = r.decode(b["held_contacts"])
    bodies.contact_cache.restore(r.decode(b["contact_cache"]))
    bodies.after_cache.restore(r.decode(b["after_cache"]))
    bodies.coupling.counts = r.decode(b["counts"])
    bodies._warned_travel = b.get("warned_travel", False)  # (states saved before it was kept: not warned)
    for emitter, m in zip(scene._emitters, meta["emitters"]):
        emitter.restore(r.decode(m))
    scene._sinks.removed = meta["removed"]
    if scene._pairs is not None:
        p = meta["pairs"]
        pairs = scene._pairs
        r.restore(pairs, p["self"], RESET["pairs"])
        r.restore(pairs.grid, p["grid"], RESET["grid"])
        r.restore(pairs.lists, p["lists"], RESET["lists"])
        r.restore(pairs.springs, p["springs"], RESET["springs"])


def frame_data(scene) -> export.Frame:
    """The scene now as the exporters take it (export.Frame)."""
    store = scene._bodies.store
    poses = tuple(export.BodyPose(shape=e.shape, position=store.x[b].copy(), rotation=store.R[b].copy(),
                                  velocity=store.v[b].copy(), angular_velocity=store.omega(b),
                                  shape_center=np.asarray(e.center, float).copy(),
                                  shape_rotation=np.asarray(e.rotation, float).copy())
                  for b, e in enumerate(store.entries))
    return export.Frame(positions=scene.positions(), velocities=scene.velocities(), radii=scene.radii(),
                        masses=scene.masses(), ids=scene.ids(), time=scene.time, frame=scene.frame,
                        frame_rate=1.0 / scene.frame_time, bodies=poses)
