"""Frames of a run written as files that other tools read: PLY, NPZ and USD.

A `Frame` is a snapshot of the particles (and the rigid bodies' poses) as plain numpy
arrays, so this module needs no Taichi field and no scene: whoever steps the simulation
builds the Frame, this module only writes it.

- PLY (binary little-endian, through plyfile): one vertex per particle with x y z, vx vy vz,
  radius (float32) and id (int32). Blender, Houdini, trimesh and plyfile read it as a point
  cloud with extra attributes.
- NPZ (numpy): every quantity at its own dtype, with the time, the frame number and the
  bodies' poses; the way to reload a frame in Python without loss.
- USD (usd-core, an optional extra imported only here): `UsdRecorder` gathers many frames
  into one layer of time samples (the particles as one UsdGeom.Points prim whose count may
  change from frame to frame, each body as an Xform carrying its shape); `write_usd` writes
  a single frame.

Every file is written to a temporary name in its folder and moved into place with
os.replace (`atomic_write`), so neither a reader nor a crash ever sees half a file.
"""

from __future__ import annotations

import os
import secrets
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import validate
from .geometry.colliders import Box, Capsule, Cylinder, Sphere
from .geometry.mesh_sdf import MeshSDF
from .geometry.triangle_mesh import TriangleMesh

FORMATS = ("ply", "npz", "usd")
EXTENSIONS = {".ply": "ply", ".npz": "npz", ".usd": "usd", ".usda": "usd", ".usdc": "usd"}
USD_MISSING = "USD export needs usd-core: pip install 'tai_coll[usd]'"
USD_SHAPES = (Box, Sphere, Cylinder, Capsule, TriangleMesh, MeshSDF)  # the body shapes USD draws
PLY_PROPERTIES = ("x", "y", "z", "vx", "vy", "vz", "radius", "id")

_INT32 = np.iinfo(np.int32)


# ---------------------------------------------------------------------- the data written
def _array(owner: str, name: str, value, shape: tuple, kinds: str) -> np.ndarray:
    """`value` as an array of `shape` (None: any length there) whose dtype kind is in `kinds`;
    integers become float64 where floats are expected, float32 and float64 stay as they are."""
    arr = np.asarray(value)
    if arr.dtype.kind not in kinds:
        raise TypeError(f"{owner}.{name} must hold {'integers' if kinds == 'iu' else 'real numbers'}; "
                        f"got dtype {arr.dtype}")
    if arr.ndim != len(shape) or any(want is not None and got != want for got, want in zip(arr.shape, shape)):
        wanted = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        raise ValueError(f"{owner}.{name} must have shape {wanted}; got {arr.shape}")
    if "f" in kinds and arr.dtype.kind in "iu":
        arr = arr.astype(np.float64)
    return arr


@dataclass(frozen=True, eq=False)
class BodyPose:
    """Where a rigid body is in one frame.

    shape: its collider (tai_coll.Box, Sphere, Cylinder, Capsule, TriangleMesh or MeshSDF).
    position (m): centre of mass, world; rotation: 3x3, body frame -> world; velocity (m/s)
    and angular_velocity (rad/s), world. shape_center (m) and shape_rotation (3x3): the
    pose of the shape's local frame in the world now (what USD draws the shape with).
    """

    shape: object
    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    angular_velocity: np.ndarray
    shape_center: np.ndarray
    shape_rotation: np.ndarray

    def __post_init__(self):
        for name in ("position", "velocity", "angular_velocity", "shape_center"):
            object.__setattr__(self, name, _array("BodyPose", name, getattr(self, name), (3,), "iuf"))
        for name in ("rotation", "shape_rotation"):
            object.__setattr__(self, name, _array("BodyPose", name, getattr(self, name), (3, 3), "iuf"))


@dataclass(frozen=True, eq=False)
class Frame:
    """One frame of a run, as numpy arrays (N particles, N may be 0).

    positions (m) and velocities (m/s): (N, 3), float32 or float64; radii (m) and masses
    (kg): (N,); ids: (N,) integers, unique, ascending (a particle keeps its id for the whole
    run, so tools can follow it while emitters add particles and sinks remove them). time
    (s); frame: the frame number (0 is the initial state); frame_rate: frames per second;
    bodies: one BodyPose per rigid body, in the scene's order.

    The constructor checks shapes and dtypes (cheap: no pass over the values) and stores
    arrays; a list of bodies becomes a tuple.
    """

    positions: np.ndarray
    velocities: np.ndarray
    radii: np.ndarray
    masses: np.ndarray
    ids: np.ndarray
    time: float
    frame: int
    frame_rate: float
    bodies: tuple = ()

    def __post_init__(self):
        positions = _array("Frame", "positions", self.positions, (None, 3), "iuf")
        n = len(positions)
        fields = {"positions": positions,
                  "velocities": _array("Frame", "velocities", self.velocities, (n, 3), "iuf"),
                  "radii": _array("Frame", "radii", self.radii, (n,), "iuf"),
                  "masses": _array("Frame", "masses", self.masses, (n,), "iuf"),
                  "ids": _array("Frame", "ids", self.ids, (n,), "iu").astype(np.int64, copy=False),
                  "time": validate.real("time", self.time, stored=False),
                  "frame": validate.integer("frame", self.frame, low=0),
                  "frame_rate": validate.real("frame_rate", self.frame_rate, low=0.0, low_open=True, stored=False)}
        if not isinstance(self.bodies, (tuple, list)):
            raise TypeError(f"Frame.bodies must be a tuple of BodyPose; got {type(self.bodies).__name__}")
        for k, body in enumerate(self.bodies):
            if not isinstance(body, BodyPose):
                raise TypeError(f"Frame.bodies[{k}] must be a BodyPose; got {type(body).__name__}")
        fields["bodies"] = tuple(self.bodies)
        for name, value in fields.items():
            object.__setattr__(self, name, value)

    @property
    def count(self) -> int:
        """The number of particles, N."""
        return len(self.positions)


# ---------------------------------------------------------------------- paths and atomic files
def _check_path(path) -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path must be a str or os.PathLike; got {type(path).__name__}")
    text = os.fspath(path)
    if not isinstance(text, str):
        raise TypeError(f"path must name the file as text; got {type(text).__name__}")
    return Path(text)


def _check_frame(frame) -> Frame:
    if not isinstance(frame, Frame):
        raise TypeError(f"frame must be a tai_coll.export.Frame; got {type(frame).__name__}")
    return frame


def format_of(path) -> str:
    """"ply", "npz" or "usd", from the file's extension (.ply, .npz, .usd/.usda/.usdc, any case)."""
    suffix = _check_path(path).suffix
    try:
        return EXTENSIONS[suffix.lower()]
    except KeyError:
        raise ValueError(f"path must end in one of {', '.join(EXTENSIONS)}; got "
                         f"{repr(suffix) if suffix else 'no extension'} in {os.fspath(path)!r}") from None


def atomic_write(path, writer) -> Path:
    """Write a file so that it appears whole or not at all.

    writer(temporary_path: str) writes the complete file at a temporary name in the target's
    folder; that name ends in the target's extension (libraries that pick a format by it,
    or append one, see the right one). The file is then flushed to disk (fsync) and moved
    onto `path` with os.replace, atomic on POSIX and Windows. If anything raises, the
    temporary file is removed and an existing file at `path` is left as it was. Returns
    `path` as a Path.
    """
    path = _check_path(path)
    if not callable(writer):
        raise TypeError(f"writer must be callable as writer(temporary_path); got {type(writer).__name__}")
    # hidden, unique per process and call, and with the final extension last
    temporary = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp{path.suffix}")
    try:
        writer(str(temporary))
        # the bytes must be on disk before the rename makes them the file, or a power cut
        # could leave an empty file under the final name
        fd = os.open(temporary, os.O_RDWR | getattr(os, "O_BINARY", 0))
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
    _fsync_folder(path.parent)
    return path


def _fsync_folder(folder: Path) -> None:
    """Make the rename itself durable where the platform allows it (POSIX); best effort."""
    if os.name != "posix":
        return
    try:
        fd = os.open(folder if str(folder) else ".", os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


# ---------------------------------------------------------------------- PLY and NPZ
def write_ply(path, frame: Frame) -> Path:
    """Binary little-endian PLY of the particles: element `vertex` with x, y, z, vx, vy, vz,
    radius (float32) and id (int32). ValueError naming `ids` if an id does not fit int32."""
    path = _check_path(path)
    frame = _check_frame(frame)
    import plyfile  # only PLY needs it: importing tai_coll stays as light as before

    ids = frame.ids
    if len(ids) and (ids.min() < _INT32.min or ids.max() > _INT32.max):
        bad = ids[(ids < _INT32.min) | (ids > _INT32.max)][0]
        raise ValueError(f"ids must fit a PLY int32 ({_INT32.min} to {_INT32.max}); got {bad}")
    vertex = np.empty(frame.count, dtype=[(name, "<f4") for name in PLY_PROPERTIES[:-1]] + [("id", "<i4")])
    for axis, name in enumerate("xyz"):
        vertex[name] = frame.positions[:, axis]
        vertex["v" + name] = frame.velocities[:, axis]
    vertex["radius"] = frame.radii
    vertex["id"] = ids
    data = plyfile.PlyData([plyfile.PlyElement.describe(vertex, "vertex")], text=False, byte_order="<",
                           comments=[f"tai_coll frame {frame.frame}, time {frame.time!r} s, "
                                     f"{frame.frame_rate!r} frames per second"])
    return atomic_write(path, data.write)


def npz_arrays(frame: Frame) -> dict:
    """The arrays write_npz stores, by key: positions, velocities, radii, masses, ids, time,
    frame, frame_rate and, with bodies, body_positions (B, 3), body_rotations (B, 3, 3),
    body_velocities and body_angular_velocities (B, 3)."""
    frame = _check_frame(frame)
    arrays = {"positions": frame.positions, "velocities": frame.velocities, "radii": frame.radii,
              "masses": frame.masses, "ids": frame.ids, "time": np.float64(frame.time),
              "frame": np.int64(frame.frame), "frame_rate": np.float64(frame.frame_rate)}
    if frame.bodies:
        for key, field in (("body_positions", "position"), ("body_rotations", "rotation"),
                           ("body_velocities", "velocity"), ("body_angular_velocities", "angular_velocity")):
            arrays[key] = np.stack([getattr(body, field) for body in frame.bodies])
    return arrays


def write_npz(path, frame: Frame) -> Path:
    """An uncompressed .npz (np.savez) of `npz_arrays(frame)`, written atomically."""
    path = _check_path(path)
    arrays = npz_arrays(frame)

    def write(temporary):
        # a file object, not a name: numpy would append ".npz" to a name ending otherwise
        with open(temporary, "wb") as file:
            np.savez(file, **arrays)

    return atomic_write(path, write)


# ---------------------------------------------------------------------- USD
def _pxr():
    """The pxr modules, imported on first use: usd-core is an optional extra."""
    try:
        from pxr import Gf, Usd, UsdGeom, Vt
    except ImportError as error:
        raise ImportError(USD_MISSING) from error
    return Gf, Usd, UsdGeom, Vt


def usd_matrix(rotation, translation):
    """Gf.Matrix4d of the pose x -> rotation @ x + translation. USD multiplies row vectors
    from the left (x' = x M), so M holds rotation transposed, and the translation in its
    last row."""
    Gf = _pxr()[0]
    m = np.eye(4)
    m[:3, :3] = np.asarray(rotation, dtype=np.float64).T
    m[3, :3] = translation
    return Gf.Matrix4d(m.tolist())


def mesh_of(shape) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of a TriangleMesh or MeshSDF in its local frame (whose origin is
    the centre of the mesh's bounding box)."""
    if isinstance(shape, TriangleMesh):
        return np.asarray(shape.vertices, dtype=np.float64), np.asarray(shape.faces, dtype=np.int64)
    if isinstance(shape, MeshSDF):  # keeps the source trimesh and the centre it shifted by
        vertices = np.asarray(shape.mesh.vertices, dtype=np.float64) - shape.mesh_center
        return vertices, np.asarray(shape.mesh.faces, dtype=np.int64)
    raise TypeError(f"shape must be a TriangleMesh or MeshSDF; got {type(shape).__name__}")


def _extent(Vt, lower, upper):
    return Vt.Vec3fArray.FromNumpy(np.array([lower, upper], dtype=np.float32))


def _define_shape(stage, path: str, shape):
    """Author the shape's gprim at `path`, in the shape's local frame (axial shapes along y)."""
    Gf, _, UsdGeom, Vt = _pxr()
    if isinstance(shape, Box):
        half = np.asarray(shape.half_extents, dtype=np.float64)
        gprim = UsdGeom.Cube.Define(stage, path)
        gprim.CreateSizeAttr(2.0)
        gprim.AddScaleOp().Set(Gf.Vec3f(*half.tolist()))  # the cube of size 2 spans -1..1
        gprim.CreateExtentAttr(_extent(Vt, [-1.0] * 3, [1.0] * 3))
    elif isinstance(shape, Sphere):
        r = float(shape.radius)
        gprim = UsdGeom.Sphere.Define(stage, path)
        gprim.CreateRadiusAttr(r)
        gprim.CreateExtentAttr(_extent(Vt, [-r] * 3, [r] * 3))
    elif isinstance(shape, (Cylinder, Capsule)):
        r, h = float(shape.radius), float(shape.half_height)
        if isinstance(shape, Cylinder):
            gprim, cap = UsdGeom.Cylinder.Define(stage, path), 0.0
        else:  # USD's capsule height is its spine, without the two half spheres, as ours
            gprim, cap = UsdGeom.Capsule.Define(stage, path), r
        gprim.CreateAxisAttr(UsdGeom.Tokens.y)
        gprim.CreateRadiusAttr(r)
        gprim.CreateHeightAttr(2.0 * h)
        gprim.CreateExtentAttr(_extent(Vt, [-r, -h - cap, -r], [r, h + cap, r]))
    elif isinstance(shape, (TriangleMesh, MeshSDF)):
        vertices, faces = mesh_of(shape)
        gprim = UsdGeom.Mesh.Define(stage, path)
        gprim.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(vertices, dtype=np.float32)))
        gprim.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, dtype=np.int32)))
        gprim.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(faces.ravel(), dtype=np.int32)))
        gprim.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)  # flat triangles, not a subdivision cage
        gprim.CreateExtentAttr(_extent(Vt, vertices.min(axis=0), vertices.max(axis=0)))
    else:
        raise TypeError(f"shape must be one of {', '.join(c.__name__ for c in USD_SHAPES)}; "
                        f"got {type(shape).__name__}")
    return gprim


class UsdRecorder:
    """Frames gathered into one USD layer of time samples.

        with UsdRecorder("out/run.usdc", frame_rate=60) as usd:
            for frame in frames:
                usd.add(frame)

    path: the file, .usd or .usdc (binary crate) or .usda (text). frame_rate: frames per
    second; one time code is one frame (timeCodesPerSecond = framesPerSecond = frame_rate),
    metres (metersPerUnit = 1), y up, default prim /World.

    Particles: the UsdGeom.Points prim /World/particles with time samples of points, widths
    (2 radii), velocities (m/s) and ids; the count may change between frames. Bodies, by
    their place in Frame.bodies: /World/bodies/body_<k>, an Xform whose transform is sampled
    at every frame, with the shape authored once as its child `shape` in the shape's local
    frame. A body missing from some frame is invisible at that frame.

    The stage is built in memory; save() writes it (atomically, replacing any file there),
    and leaving a `with` block saves what was added, also when the block raises.

    keep_until (keyword only; an int >= 0, or None): continue the layer already at `path`,
    as a resumed run does (`tai-coll run --resume`). None: a new layer, as above. An int F:
    if a file exists at `path` it is read into memory (the file itself is untouched until
    save()), it must be a layer this class wrote (a /World/particles Points prim; else
    ValueError) at timeCodesPerSecond == frame_rate (else ValueError), and every time
    sample after F is dropped from it (particles and bodies, visibility included; a body
    first seen after F is removed); later add() calls then go on exactly as if this
    recorder had added the kept frames itself. No file at `path`: a new layer.
    """

    def __init__(self, path, frame_rate: float, *, keep_until=None):
        self.path = _check_path(path)
        if format_of(self.path) != "usd":
            raise ValueError(f"path must end in .usd, .usda or .usdc for a USD layer; got {os.fspath(path)!r}")
        self.frame_rate = validate.real("frame_rate", frame_rate, low=0.0, low_open=True, stored=False)
        if keep_until is not None:
            keep_until = validate.integer("keep_until", keep_until, low=0)
        self.keep_until = keep_until
        _, Usd, UsdGeom, _ = _pxr()
        self.stage = Usd.Stage.CreateInMemory()
        self._times = set()  # time codes added
        self._bodies = []  # per body: [transform op, time codes where present, time codes with visibility]
        if keep_until is not None and self.path.exists():
            self._continue(keep_until)
            return
        UsdGeom.SetStageMetersPerUnit(self.stage, 1.0)
        UsdGeom.SetStageUpAxis(self.stage, UsdGeom.Tokens.y)
        self.stage.SetTimeCodesPerSecond(self.frame_rate)
        self.stage.SetFramesPerSecond(self.frame_rate)
        self.stage.SetDefaultPrim(UsdGeom.Xform.Define(self.stage, "/World").GetPrim())
        self.particles = UsdGeom.Points.Define(self.stage, "/World/particles")
        self.particles.SetWidthsInterpolation(UsdGeom.Tokens.vertex)

    def _continue(self, keep_until: int) -> None:
        """Load the layer at self.path into the in-memory stage, drop its time samples after
        keep_until and rebuild _times and _bodies from what is left (see __init__)."""
        from pxr import Sdf, Tf

        _, _, UsdGeom, _ = _pxr()
        where = os.fspath(self.path)

        def refuse(why):
            return ValueError(f"cannot continue the USD layer {where!r} (keep_until={keep_until}): {why}")

        try:
            source = Sdf.Layer.OpenAsAnonymous(where)
        except Tf.ErrorException as error:
            raise refuse(f"USD cannot read it ({str(error).strip()})") from None
        if source is None:
            raise refuse("USD cannot read it")
        particles = source.GetPrimAtPath("/World/particles")
        if particles is None or particles.typeName != "Points":
            raise refuse("it has no /World/particles Points prim, so it is not a layer UsdRecorder wrote")
        rate = source.timeCodesPerSecond
        if not np.isclose(rate, self.frame_rate, rtol=1e-9, atol=0.0):
            raise refuse(f"its timeCodesPerSecond is {rate!r}, not this recorder's frame_rate {self.frame_rate!r}")

        layer = self.stage.GetRootLayer()
        layer.TransferContent(source)
        del source
        # every time sample after keep_until, on every attribute of the layer
        attributes = []
        layer.Traverse(Sdf.Path.absoluteRootPath,
                       lambda path: attributes.append(path) if path.IsPropertyPath() else None)
        with Sdf.ChangeBlock():
            for path in attributes:
                times = layer.ListTimeSamplesForPath(path)
                for t in times:
                    if t > keep_until:
                        layer.EraseTimeSample(path, t)
                spec = layer.GetAttributeAtPath(path)
                if times and not layer.GetNumTimeSamplesForPath(path) and spec and not spec.HasDefaultValue() \
                        and set(spec.ListInfoKeys()) <= {"typeName", "custom", "variability"}:
                    spec.owner.RemoveProperty(spec)  # samples only, all after keep_until: not authored yet
        # the rest as __init__ sets it for a new layer (the same values in a layer it wrote)
        UsdGeom.SetStageMetersPerUnit(self.stage, 1.0)
        UsdGeom.SetStageUpAxis(self.stage, UsdGeom.Tokens.y)
        self.stage.SetTimeCodesPerSecond(self.frame_rate)
        self.stage.SetFramesPerSecond(self.frame_rate)
        self.stage.SetDefaultPrim(self.stage.GetPrimAtPath("/World"))
        self.particles = UsdGeom.Points(self.stage.GetPrimAtPath("/World/particles"))

        # every add() authors the points: their time codes are the frames added
        self._times = {float(t) for t in self.particles.GetPointsAttr().GetTimeSamples()}
        bodies = []  # body_0, body_1, ... as _define_body named them
        while self.stage.GetPrimAtPath(f"/World/bodies/body_{len(bodies)}"):
            bodies.append(self.stage.GetPrimAtPath(f"/World/bodies/body_{len(bodies)}"))
        transforms = [prim.GetAttribute("xformOp:transform") for prim in bodies]  # _define_body's op
        # a body is defined by the first frame that has it; one that no kept frame has, this
        # recorder would not have made yet (a body k + 1 only comes with a body k)
        kept = [bool(attribute and attribute.GetNumTimeSamples()) for attribute in transforms]
        count = kept.index(False) if False in kept else len(kept)
        if any(kept[count:]):
            raise refuse(f"body_{count} has no transform sample up to frame {keep_until} but "
                         f"body_{kept.index(True, count)} has; UsdRecorder adds bodies in order")
        for prim in reversed(bodies[count:]):
            self.stage.RemovePrim(prim.GetPath())
        ops = [UsdGeom.XformOp(attribute) for attribute in transforms[:count]]
        for prim, op in zip(bodies, ops):
            if op.GetOpType() != UsdGeom.XformOp.TypeTransform or not any(
                    op.GetName() == other.GetName() for other in UsdGeom.Xformable(prim).GetOrderedXformOps()):
                raise refuse(f"{prim.GetPath()} does not use its xformOp:transform, so it is not a body "
                             f"UsdRecorder wrote")
        scope = self.stage.GetPrimAtPath("/World/bodies")
        if scope and not count and not scope.GetAllChildren():
            self.stage.RemovePrim(scope.GetPath())  # made with the first body
        for op in ops:
            imageable = UsdGeom.Imageable(op.GetAttr().GetPrim())
            visibility = imageable.GetVisibilityAttr()
            shown = {float(t): visibility.Get(t) for t in visibility.GetTimeSamples()}
            sampled = {float(t) for t in op.GetTimeSamples()}
            # where visibility was authored it says whether the body was there (a frame added
            # again without it keeps its old transform sample); elsewhere the transform does
            present = {t for t in self._times
                       if (shown[t] != UsdGeom.Tokens.invisible if t in shown else t in sampled)}
            if present == self._times:  # there in every kept frame: as if it had never been missing
                if visibility.IsAuthored():
                    imageable.GetPrim().RemoveProperty(visibility.GetName())
                done = set()
            else:
                done = set(shown) & self._times
            self._bodies.append([op, present, done])
        self._author_visibility()  # visibility where a kept frame lacks it (none in a layer this class wrote)
        if self._times:
            self.stage.SetStartTimeCode(min(self._times))
            self.stage.SetEndTimeCode(max(self._times))
        else:  # nothing kept: no range, as a new layer before its first add()
            layer.ClearStartTimeCode()
            layer.ClearEndTimeCode()

    @property
    def time_codes(self) -> list:
        """The time codes (frame numbers) added so far, ascending."""
        return sorted(self._times)

    def add(self, frame: Frame) -> None:
        """Author `frame` at time code frame.frame (adding a frame number again replaces it).
        Its frame_rate must be the recorder's."""
        frame = _check_frame(frame)
        if not np.isclose(frame.frame_rate, self.frame_rate, rtol=1e-9, atol=0.0):
            raise ValueError(f"frame.frame_rate is {frame.frame_rate!r}; this recorder was made with frame_rate "
                             f"{self.frame_rate!r} and one time code per frame")
        for k in range(len(self._bodies), len(frame.bodies)):  # new bodies: a kind USD can draw, before any write
            if not isinstance(frame.bodies[k].shape, USD_SHAPES):
                raise TypeError(f"frame.bodies[{k}].shape must be one of {', '.join(c.__name__ for c in USD_SHAPES)} "
                                f"to write it to USD; got {type(frame.bodies[k].shape).__name__}")
        _, _, UsdGeom, Vt = _pxr()
        t = float(frame.frame)
        points = np.ascontiguousarray(frame.positions, dtype=np.float32)
        radii = np.ascontiguousarray(frame.radii, dtype=np.float32)
        self.particles.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(points), t)
        self.particles.GetWidthsAttr().Set(Vt.FloatArray.FromNumpy(2.0 * radii), t)
        self.particles.GetVelocitiesAttr().Set(
            Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(frame.velocities, dtype=np.float32)), t)
        self.particles.GetIdsAttr().Set(Vt.Int64Array.FromNumpy(np.ascontiguousarray(frame.ids)), t)
        if frame.count:  # the bounds of the spheres; an empty cloud gets a point box at the origin
            lower, upper = (points - radii[:, None]).min(axis=0), (points + radii[:, None]).max(axis=0)
        else:
            lower = upper = np.zeros(3)
        self.particles.GetExtentAttr().Set(_extent(Vt, lower, upper), t)

        self._times.add(t)
        for _, _, done in self._bodies:
            done.discard(t)  # this time code's visibility is authored again below
        for k, body in enumerate(frame.bodies):
            if k == len(self._bodies):  # first seen in this frame
                self._bodies.append([self._define_body(k, body.shape), set(), set()])
            op, present, _ = self._bodies[k]
            op.Set(usd_matrix(body.shape_rotation, body.shape_center), t)
            present.add(t)
        for k in range(len(frame.bodies), len(self._bodies)):
            self._bodies[k][1].discard(t)
        self._author_visibility()
        self.stage.SetStartTimeCode(min(self._times))
        self.stage.SetEndTimeCode(max(self._times))

    def _define_body(self, k: int, shape):
        _, _, UsdGeom, _ = _pxr()
        path = f"/World/bodies/body_{k}"
        if not self.stage.GetPrimAtPath("/World/bodies"):
            UsdGeom.Scope.Define(self.stage, "/World/bodies")
        xform = UsdGeom.Xform.Define(self.stage, path)
        _define_shape(self.stage, f"{path}/shape", shape)
        return xform.AddTransformOp()

    def _author_visibility(self):
        """Visibility samples for bodies missing from some frame: a body shows where it was
        present. A body present in every frame gets none; once one is missing, every time
        code gets a sample (USD holds the first and last samples before and after them)."""
        _, _, UsdGeom, _ = _pxr()
        for op, present, done in self._bodies:
            if present == self._times and not done:
                continue
            visibility = UsdGeom.Imageable(op.GetAttr().GetPrim()).GetVisibilityAttr()
            for t in self._times - done:
                visibility.Set(UsdGeom.Tokens.inherited if t in present else UsdGeom.Tokens.invisible, t)
            done.update(self._times)

    def save(self) -> Path:
        """Write the layer to `path` (atomically; the format follows the extension)."""
        layer = self.stage.GetRootLayer()

        def export(temporary):
            if not layer.Export(temporary):
                raise OSError(f"USD could not write {temporary}")

        return atomic_write(self.path, export)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.save()
        return False


def write_usd(path, frame: Frame) -> Path:
    """A USD layer of one frame (at time code frame.frame), through UsdRecorder. The
    particles' attributes also get the frame as their default value, so a reader asking
    without a time code (attr.Get()) sees it too."""
    path = _check_path(path)
    frame = _check_frame(frame)
    recorder = UsdRecorder(path, frame.frame_rate)
    recorder.add(frame)
    particles = recorder.particles
    for attribute in (particles.GetPointsAttr(), particles.GetWidthsAttr(), particles.GetVelocitiesAttr(),
                      particles.GetIdsAttr(), particles.GetExtentAttr()):
        attribute.Set(attribute.Get(float(frame.frame)))
    return recorder.save()


# ---------------------------------------------------------------------- dispatch
WRITERS = {"ply": write_ply, "npz": write_npz, "usd": write_usd}


def save_frame(path, frame: Frame) -> Path:
    """Write `frame` in the format its extension names (format_of), creating missing folders."""
    path = _check_path(path)
    frame = _check_frame(frame)
    writer = WRITERS[format_of(path)]
    path.parent.mkdir(parents=True, exist_ok=True)
    return writer(path, frame)
