"""Frame export: PLY, NPZ and USD files read back by other readers (trimesh, plyfile, numpy,
pxr) hold what the Frame held; bodies' USD transforms put their shapes where the pose says;
files appear whole or not at all. Frames are built from numpy here: no kernel runs."""

import dataclasses
import os
import sys

import numpy as np
import plyfile
import pytest
import trimesh

import tai_coll as tc
from tai_coll import export
from tai_coll.export import BodyPose, Frame, UsdRecorder, atomic_write, format_of, save_frame

FPS = 24.0


def make_frame(n, *, frame=0, seed=0, bodies=(), dtype=np.float64, first_id=0):
    """n particles with distinct random values in every field; ids ascending with gaps."""
    rng = np.random.default_rng(seed)
    return Frame(positions=rng.uniform(-1.0, 1.0, (n, 3)).astype(dtype),
                 velocities=rng.normal(0.0, 2.0, (n, 3)).astype(dtype),
                 radii=rng.uniform(0.005, 0.02, n).astype(dtype),
                 masses=rng.uniform(0.1, 1.0, n).astype(dtype),
                 ids=first_id + 3 * np.arange(n, dtype=np.int64),
                 time=frame / FPS, frame=frame, frame_rate=FPS, bodies=tuple(bodies))


def turn(seed):
    """A rotation matrix about a random axis by a random angle."""
    rng = np.random.default_rng(seed)
    return tc.rotation_matrix(rng.normal(size=3), rng.uniform(0.3, 2.5))


def pose(shape, *, seed=0):
    """A body of `shape` at a random pose; its shape frame sits away from the centre of mass."""
    rng = np.random.default_rng(seed)
    rotation = turn(seed)
    position = rng.uniform(-2.0, 2.0, 3)
    return BodyPose(shape=shape, position=position, rotation=rotation, velocity=rng.normal(size=3),
                    angular_velocity=rng.normal(size=3), shape_center=position + rotation @ [0.1, -0.2, 0.05],
                    shape_rotation=rotation)


def octahedron():
    vertices = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64)
    faces = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return vertices * [0.3, 0.2, 0.1] + [5.0, 0.0, 0.0], faces


def usd_points(path, time):
    """(points, widths, velocities, ids) of /World/particles at a time code."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    points = UsdGeom.Points(stage.GetPrimAtPath("/World/particles"))
    return (np.array(points.GetPointsAttr().Get(time)).reshape(-1, 3), np.array(points.GetWidthsAttr().Get(time)),
            np.array(points.GetVelocitiesAttr().Get(time)).reshape(-1, 3),
            np.array(points.GetIdsAttr().Get(time), dtype=np.int64))


# ---------------------------------------------------------------------- paths, arguments
@pytest.mark.parametrize("name, expected", [("a.ply", "ply"), ("a.PLY", "ply"), ("a.npz", "npz"), ("b/a.usd", "usd"),
                                            ("a.usda", "usd"), ("a.USDC", "usd")])
def test_the_extension_names_the_format(name, expected):
    assert format_of(name) == expected and format_of(os.path.join("x", name)) == expected
    assert expected in export.FORMATS


def test_an_unknown_extension_is_refused_naming_it(tmp_path):
    with pytest.raises(ValueError, match=r"path must end in .*'\.obj'"):
        format_of("frame.obj")
    with pytest.raises(ValueError, match="no extension"):
        format_of("frame")
    with pytest.raises(ValueError, match=r"'\.vtk'"):
        save_frame(tmp_path / "frame.vtk", make_frame(3))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("write", [export.write_ply, export.write_npz, save_frame])
def test_a_frame_must_be_a_frame_and_a_path_a_path(tmp_path, write):
    with pytest.raises(TypeError, match="frame must be a tai_coll.export.Frame"):
        write(tmp_path / "a.npz", {"positions": np.zeros((1, 3))})
    with pytest.raises(TypeError, match="path must be a str or os.PathLike"):
        write(3, make_frame(2))
    assert list(tmp_path.iterdir()) == []


def test_a_frame_checks_its_fields():
    good = make_frame(4)
    fields = dict(positions=good.positions, velocities=good.velocities, radii=good.radii, masses=good.masses,
                  ids=good.ids, time=0.0, frame=0, frame_rate=FPS)
    with pytest.raises(ValueError, match=r"Frame.velocities must have shape \(4, 3\)"):
        Frame(**{**fields, "velocities": np.zeros((3, 3))})
    with pytest.raises(TypeError, match="Frame.ids must hold integers"):
        Frame(**{**fields, "ids": np.arange(4.0)})
    with pytest.raises(ValueError, match="frame_rate must be > 0"):
        Frame(**{**fields, "frame_rate": 0.0})
    with pytest.raises(TypeError, match=r"Frame.bodies\[0\] must be a BodyPose"):
        Frame(**fields, bodies=(tc.Sphere(),))
    with pytest.raises(ValueError, match=r"BodyPose.shape_rotation must have shape \(3, 3\)"):
        BodyPose(tc.Sphere(), np.zeros(3), np.eye(3), np.zeros(3), np.zeros(3), np.zeros(3), np.eye(4))
    assert Frame(**fields).count == 4


# ---------------------------------------------------------------------- atomic files
def test_a_failing_writer_leaves_no_file_and_no_temporary(tmp_path):
    seen = []

    def fails(temporary):
        seen.append(temporary)
        with open(temporary, "wb") as file:
            file.write(b"half a fi")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(tmp_path / "state.npz", fails)
    assert list(tmp_path.iterdir()) == []
    assert os.path.dirname(seen[0]) == str(tmp_path) and seen[0].endswith(".npz")  # same folder, same extension


def test_a_failing_writer_leaves_the_existing_file_as_it_was(tmp_path):
    target = tmp_path / "frame.ply"
    export.write_ply(target, make_frame(5))
    before = target.read_bytes()

    def fails(temporary):
        export.write_ply(temporary, make_frame(9, seed=1))
        raise KeyboardInterrupt  # not only Exceptions: an interrupted run cleans up too

    with pytest.raises(KeyboardInterrupt):
        atomic_write(target, fails)
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["frame.ply"]


def test_atomic_write_replaces_the_file_in_one_step(tmp_path):
    target = tmp_path / "state.bin"
    target.write_bytes(b"old")

    def writes_new(temporary):
        with open(temporary, "wb") as file:
            file.write(b"new")

    assert atomic_write(str(target), writes_new) == target
    assert target.read_bytes() == b"new" and [p.name for p in tmp_path.iterdir()] == ["state.bin"]


# ---------------------------------------------------------------------- PLY
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_ply_reads_back_in_trimesh_and_plyfile(tmp_path, dtype):
    frame = make_frame(50, dtype=dtype, first_id=1_000)
    path = export.write_ply(tmp_path / "frame.ply", frame)

    ply = plyfile.PlyData.read(str(path))
    assert not ply.text and ply.byte_order == "<"
    assert path.read_bytes().startswith(b"ply\nformat binary_little_endian 1.0\n")
    assert [e.name for e in ply.elements] == ["vertex"]
    vertex = ply["vertex"]
    assert tuple(p.name for p in vertex.properties) == ("x", "y", "z", "vx", "vy", "vz", "radius", "id")
    assert [vertex.data.dtype[name].str for name in vertex.data.dtype.names] == ["<f4"] * 7 + ["<i4"]
    positions = np.column_stack([vertex["x"], vertex["y"], vertex["z"]])
    velocities = np.column_stack([vertex["vx"], vertex["vy"], vertex["vz"]])
    np.testing.assert_allclose(positions, frame.positions, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(velocities, frame.velocities, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(vertex["radius"], frame.radii, rtol=1e-6)
    np.testing.assert_array_equal(vertex["id"], frame.ids)

    cloud = trimesh.load(str(path))
    assert isinstance(cloud, trimesh.PointCloud)
    np.testing.assert_allclose(cloud.vertices, frame.positions, rtol=1e-6, atol=1e-7)


def test_ply_refuses_ids_beyond_int32_before_writing(tmp_path):
    frame = make_frame(3, first_id=2**31 - 4)  # ids 2**31 - 4, - 1, + 2
    with pytest.raises(ValueError, match=r"ids must fit a PLY int32 .*got 2147483650"):
        export.write_ply(tmp_path / "frame.ply", frame)
    assert list(tmp_path.iterdir()) == []
    export.write_npz(tmp_path / "frame.npz", frame)  # NPZ keeps int64


# ---------------------------------------------------------------------- NPZ
def test_npz_holds_every_field_and_bodies_only_when_there_are_some(tmp_path):
    frame = make_frame(20, frame=7, dtype=np.float32)
    with np.load(export.write_npz(tmp_path / "plain.npz", frame)) as data:
        assert set(data.files) == {"positions", "velocities", "radii", "masses", "ids", "time", "frame", "frame_rate"}
        for key in ("positions", "velocities", "radii", "masses", "ids"):
            assert data[key].dtype == getattr(frame, key).dtype
            np.testing.assert_array_equal(data[key], getattr(frame, key))
        assert data["time"] == frame.time and data["frame"] == 7 and data["frame_rate"] == FPS

    bodies = [pose(tc.Sphere(radius=0.2), seed=1), pose(tc.Box(half_extents=(0.1, 0.2, 0.3)), seed=2)]
    frame = make_frame(20, frame=7, bodies=bodies)
    with np.load(export.write_npz(tmp_path / "bodies.npz", frame)) as data:
        assert data["body_positions"].shape == (2, 3) and data["body_rotations"].shape == (2, 3, 3)
        for key, field in (("body_positions", "position"), ("body_rotations", "rotation"),
                           ("body_velocities", "velocity"), ("body_angular_velocities", "angular_velocity")):
            np.testing.assert_array_equal(data[key], [getattr(b, field) for b in bodies])
    assert not (tmp_path / "bodies.npz.npz").exists()


def test_an_upper_case_npz_name_is_kept(tmp_path):
    path = export.write_npz(tmp_path / "FRAME.NPZ", make_frame(2))
    assert [p.name for p in tmp_path.iterdir()] == ["FRAME.NPZ"]
    with np.load(path) as data:
        assert len(data["ids"]) == 2


# ---------------------------------------------------------------------- USD
def test_usd_keeps_every_frame_as_time_samples(tmp_path):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    # an emitter adds particles, a sink removes some: 4, then 7, then 2 particles
    frames = [make_frame(4, frame=0, seed=0), make_frame(7, frame=5, seed=1, first_id=1),
              make_frame(2, frame=10, seed=2, first_id=9)]
    with UsdRecorder(tmp_path / "run.usdc", FPS) as recorder:
        for frame in frames:
            recorder.add(frame)
    assert recorder.time_codes == [0.0, 5.0, 10.0]

    stage = Usd.Stage.Open(str(tmp_path / "run.usdc"))
    assert stage.GetTimeCodesPerSecond() == FPS and stage.GetFramesPerSecond() == FPS
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 10.0)
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0 and UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert stage.GetDefaultPrim().GetPath() == "/World"
    assert stage.GetPrimAtPath("/World/particles").IsA(UsdGeom.Points)
    for frame in frames:
        points, widths, velocities, ids = usd_points(tmp_path / "run.usdc", frame.frame)
        np.testing.assert_allclose(points, frame.positions, rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(widths, 2.0 * frame.radii, rtol=1e-6)
        np.testing.assert_allclose(velocities, frame.velocities, rtol=1e-6, atol=1e-7)
        np.testing.assert_array_equal(ids, frame.ids)
    extent = np.array(UsdGeom.Points(stage.GetPrimAtPath("/World/particles")).GetExtentAttr().Get(5))
    spheres = frames[1].positions, frames[1].radii[:, None]
    np.testing.assert_allclose(extent, [np.min(spheres[0] - spheres[1], axis=0), np.max(sum(spheres), axis=0)],
                               rtol=1e-6)


@pytest.mark.parametrize("name, header", [("a.usda", b"#usda 1.0"), ("a.usd", b"PXR-USDC"), ("a.usdc", b"PXR-USDC")])
def test_usd_text_or_crate_follows_the_extension(tmp_path, name, header):
    pytest.importorskip("pxr")
    path = export.write_usd(tmp_path / name, make_frame(3))
    assert path.read_bytes().startswith(header)
    assert [p.name for p in tmp_path.iterdir()] == [name]


SHAPES = {
    "box": (lambda: tc.Box(half_extents=(0.1, 0.2, 0.3)), "Cube"),
    "sphere": (lambda: tc.Sphere(radius=0.25), "Sphere"),
    "cylinder": (lambda: tc.Cylinder(radius=0.2, half_height=0.4), "Cylinder"),
    "capsule": (lambda: tc.Capsule(radius=0.1, half_height=0.3), "Capsule"),
    "mesh": (lambda: tc.TriangleMesh(octahedron()), "Mesh"),
}


@pytest.mark.parametrize("kind", sorted(SHAPES))
def test_a_body_moves_its_shape_where_the_pose_puts_it(tmp_path, kind):
    pytest.importorskip("pxr")
    from pxr import Gf, Usd, UsdGeom

    make_shape, usd_type = SHAPES[kind]
    shape = make_shape()
    frames = [make_frame(3, frame=k, bodies=[pose(shape, seed=10 + k)]) for k in range(3)]
    with UsdRecorder(tmp_path / "run.usda", FPS) as recorder:
        for frame in frames:
            recorder.add(frame)
    stage = Usd.Stage.Open(str(tmp_path / "run.usda"))
    body = stage.GetPrimAtPath("/World/bodies/body_0")
    gprim = stage.GetPrimAtPath("/World/bodies/body_0/shape")
    assert body.IsA(UsdGeom.Xform) and gprim.GetTypeName() == usd_type
    # the shape is authored once; only the body's transform has time samples
    assert all(attribute.GetNumTimeSamples() == 0 for attribute in gprim.GetAttributes())
    local = np.random.default_rng(3).normal(size=(5, 3))
    for frame in frames:
        pose_now = frame.bodies[0]
        matrix = UsdGeom.Xformable(body).ComputeLocalToWorldTransform(frame.frame)
        world = np.array([matrix.Transform(Gf.Vec3d(*p)) for p in local])
        np.testing.assert_allclose(world, local @ pose_now.shape_rotation.T + pose_now.shape_center, atol=1e-12)
        # and the drawn shape's bounds are the shape's own, turned and moved
        bound = UsdGeom.BBoxCache(frame.frame, [UsdGeom.Tokens.default_]).ComputeWorldBound(gprim)
        box = bound.ComputeAlignedRange()
        corners = local_bounds(shape) @ pose_now.shape_rotation.T + pose_now.shape_center
        np.testing.assert_allclose([box.GetMin(), box.GetMax()], [corners.min(axis=0), corners.max(axis=0)], atol=1e-5)


def local_bounds(shape):
    """The 8 corners of the shape's bounding box in its local frame (axial shapes along y)."""
    if isinstance(shape, tc.Box):
        half = np.asarray(shape.half_extents)
    elif isinstance(shape, tc.Sphere):
        half = np.full(3, shape.radius)
    elif isinstance(shape, tc.Cylinder):
        half = np.array([shape.radius, shape.half_height, shape.radius])
    elif isinstance(shape, tc.Capsule):
        half = np.array([shape.radius, shape.half_height + shape.radius, shape.radius])
    else:
        v = np.asarray(shape.vertices)
        lo, hi = v.min(axis=0), v.max(axis=0)
        return np.array([[(lo, hi)[a][0], (lo, hi)[b][1], (lo, hi)[c][2]] for a in (0, 1) for b in (0, 1)
                         for c in (0, 1)])
    return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half


def test_usd_gprims_carry_the_shapes_sizes(tmp_path):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    shapes = [SHAPES[kind][0]() for kind in ("box", "sphere", "cylinder", "capsule", "mesh")]
    frame = make_frame(2, bodies=[pose(s, seed=k) for k, s in enumerate(shapes)])
    stage = Usd.Stage.Open(str(export.write_usd(tmp_path / "bodies.usda", frame)))
    box, sphere, cylinder, capsule, mesh = (stage.GetPrimAtPath(f"/World/bodies/body_{k}/shape") for k in range(5))
    assert UsdGeom.Cube(box).GetSizeAttr().Get() == 2.0
    scale = [op for op in UsdGeom.Xformable(box).GetOrderedXformOps() if op.GetOpType() == UsdGeom.XformOp.TypeScale]
    np.testing.assert_allclose(scale[0].Get(), [0.1, 0.2, 0.3], rtol=1e-6)
    assert UsdGeom.Sphere(sphere).GetRadiusAttr().Get() == 0.25
    for prim, schema, radius, height in ((cylinder, UsdGeom.Cylinder, 0.2, 0.8), (capsule, UsdGeom.Capsule, 0.1, 0.6)):
        assert schema(prim).GetAxisAttr().Get() == "Y"
        assert schema(prim).GetRadiusAttr().Get() == pytest.approx(radius)
        assert schema(prim).GetHeightAttr().Get() == pytest.approx(height)
    mesh = UsdGeom.Mesh(mesh)
    vertices, faces = octahedron()
    np.testing.assert_allclose(np.array(mesh.GetPointsAttr().Get()), vertices - [5.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_array_equal(np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3), faces)
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [3] * len(faces)


def test_a_baked_mesh_is_drawn_from_its_source_triangles():
    # a MeshSDF as its constructor leaves it (source mesh and the centre it shifted by), unbaked
    vertices, faces = octahedron()
    shape = object.__new__(tc.MeshSDF)
    shape.mesh = trimesh.Trimesh(vertices, faces, process=False)
    shape.mesh_center = np.array([5.0, 0.0, 0.0])
    local, local_faces = export.mesh_of(shape)
    np.testing.assert_allclose(local, vertices - [5.0, 0.0, 0.0])
    np.testing.assert_array_equal(local_faces, faces)


def test_bodies_that_come_and_go_are_hidden_where_absent(tmp_path):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    ball, crate = tc.Sphere(radius=0.1), tc.Box(half_extents=(0.1, 0.1, 0.1))
    with UsdRecorder(tmp_path / "run.usda", FPS) as recorder:
        recorder.add(make_frame(2, frame=0, bodies=[pose(ball)]))
        recorder.add(make_frame(2, frame=1, bodies=[pose(ball), pose(crate, seed=1)]))  # created on demand
        recorder.add(make_frame(2, frame=2, bodies=[pose(ball)]))
    stage = Usd.Stage.Open(str(tmp_path / "run.usda"))
    first, second = (UsdGeom.Imageable(stage.GetPrimAtPath(f"/World/bodies/body_{k}")) for k in (0, 1))
    assert stage.GetPrimAtPath("/World/bodies/body_1/shape").GetTypeName() == "Cube"
    assert [first.ComputeVisibility(t) for t in (0, 1, 2)] == ["inherited"] * 3
    assert first.GetVisibilityAttr().GetNumTimeSamples() == 0  # always there: no samples needed
    assert [second.ComputeVisibility(t) for t in (0, 1, 2)] == ["invisible", "inherited", "invisible"]


def test_usd_refuses_a_frame_at_another_rate_and_a_shape_it_cannot_draw(tmp_path):
    pytest.importorskip("pxr")
    recorder = UsdRecorder(tmp_path / "run.usda", FPS)
    frame = make_frame(2)
    with pytest.raises(ValueError, match="frame.frame_rate is 30.0; this recorder was made with frame_rate 24.0"):
        recorder.add(dataclasses.replace(frame, frame_rate=30.0))
    plane = BodyPose(tc.Plane(), np.zeros(3), np.eye(3), np.zeros(3), np.zeros(3), np.zeros(3), np.eye(3))
    with pytest.raises(TypeError, match=r"frame.bodies\[0\].shape must be one of Box, .* got Plane"):
        recorder.add(make_frame(2, bodies=[plane]))
    assert recorder.time_codes == [] and not (tmp_path / "run.usda").exists()  # nothing authored, nothing written
    with pytest.raises(ValueError, match="path must end in .usd, .usda or .usdc"):
        UsdRecorder(tmp_path / "run.ply", FPS)


def test_usd_without_usd_core_says_how_to_install_it(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pxr", None)  # import pxr now raises ImportError
    with pytest.raises(ImportError, match=r"USD export needs usd-core: pip install 'tai_coll\[usd\]'"):
        export.write_usd(tmp_path / "frame.usda", make_frame(2))
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------- all formats
def test_one_frame_is_the_same_in_every_format(tmp_path):
    pytest.importorskip("pxr")
    frame = make_frame(30, frame=4, bodies=[pose(tc.Sphere(radius=0.1))])
    paths = {ext: save_frame(tmp_path / "out" / "deeper" / f"frame.{ext}", frame) for ext in ("ply", "npz", "usda")}
    assert all(path.is_file() for path in paths.values())  # save_frame made the folders

    vertex = plyfile.PlyData.read(str(paths["ply"]))["vertex"]
    ply = np.column_stack([vertex["x"], vertex["y"], vertex["z"]]), vertex["radius"], vertex["id"]
    with np.load(paths["npz"]) as data:
        npz = data["positions"], data["radii"], data["ids"]
    points, widths, _, ids = usd_points(paths["usda"], 4)
    usd = points, widths / 2.0, ids
    for positions, radii, ids in (ply, npz, usd):
        np.testing.assert_allclose(positions, frame.positions, rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(radii, frame.radii, rtol=1e-6)
        np.testing.assert_array_equal(ids, frame.ids)


@pytest.mark.parametrize("ext", ["ply", "npz", "usda", "usdc"])
def test_an_empty_frame_writes_a_valid_file(tmp_path, ext):
    if ext.startswith("usd"):
        pytest.importorskip("pxr")
    frame = make_frame(0, frame=2)
    path = save_frame(tmp_path / f"empty.{ext}", frame)
    if ext == "ply":
        vertex = plyfile.PlyData.read(str(path))["vertex"]
        assert vertex.count == 0 and tuple(p.name for p in vertex.properties) == export.PLY_PROPERTIES
    elif ext == "npz":
        with np.load(path) as data:
            assert data["positions"].shape == (0, 3) and data["ids"].dtype == np.int64 and data["frame"] == 2
    else:
        points, widths, velocities, ids = usd_points(path, 2)
        assert points.shape == (0, 3) and widths.size == velocities.size == ids.size == 0


# ---------------------------------------------------------------------- USD: continuing a layer (--resume)
def open_fresh(path):
    """A stage of the file as it is on disk now (an anonymous copy: never a layer cached
    from an earlier open of the same path)."""
    from pxr import Sdf, Usd

    return Usd.Stage.Open(Sdf.Layer.OpenAsAnonymous(str(path)))


def first_run():
    """Frames 0..5: a ball from frame 2 on, a crate only in frame 5."""
    ball, crate = tc.Sphere(radius=0.1), tc.Box(half_extents=(0.1, 0.2, 0.3))
    return [make_frame(3 + k, frame=k, seed=k,
                       bodies=([pose(ball, seed=20 + k)] if k >= 2 else []) + ([pose(crate, seed=40)] if k == 5 else []))
            for k in range(6)]


def second_run():
    """Frames 4..6 of the resumed run, unlike the first run's 4 and 5: the ball is missing from
    frame 5, and frame 6 brings a second body of another shape."""
    ball, drum = tc.Sphere(radius=0.1), tc.Cylinder(radius=0.2, half_height=0.3)
    bodies = {4: [pose(ball, seed=54)], 5: [], 6: [pose(ball, seed=56), pose(drum, seed=66)]}
    return [make_frame(9 - k, frame=k, seed=100 + k, first_id=7, bodies=bodies[k]) for k in (4, 5, 6)]


def recorded(path, frames, **kwargs):
    recorder = UsdRecorder(path, FPS, **kwargs)
    for frame in frames:
        recorder.add(frame)
    recorder.save()
    return recorder


@pytest.mark.parametrize("name", ["run.usda", "run.usdc", "run.usd"])
def test_a_recorder_continues_a_layer_after_keep_until(tmp_path, name):
    pytest.importorskip("pxr")
    from pxr import Gf, UsdGeom

    path = tmp_path / name
    first, second = first_run(), second_run()
    recorded(path, first)
    before = path.read_bytes()

    recorder = UsdRecorder(path, FPS, keep_until=3)
    assert recorder.time_codes == [0.0, 1.0, 2.0, 3.0]
    for frame in second:
        recorder.add(frame)
    assert path.read_bytes() == before  # nothing on disk changes until save()
    assert recorder.save() == path
    assert recorder.time_codes == [float(t) for t in range(7)]
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]

    stage = open_fresh(path)
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 6.0)
    assert stage.GetTimeCodesPerSecond() == FPS and stage.GetFramesPerSecond() == FPS
    assert stage.GetDefaultPrim().GetPath() == "/World"
    particles = UsdGeom.Points(stage.GetPrimAtPath("/World/particles"))
    for attribute in (particles.GetPointsAttr(), particles.GetWidthsAttr(), particles.GetVelocitiesAttr(),
                      particles.GetIdsAttr(), particles.GetExtentAttr()):
        assert attribute.GetTimeSamples() == [float(t) for t in range(7)], attribute.GetName()
    for frame in first[:4] + second:  # 0..3 from the first run, 4..6 from the second
        t = frame.frame
        np.testing.assert_allclose(np.array(particles.GetPointsAttr().Get(t)), frame.positions, rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(np.array(particles.GetWidthsAttr().Get(t)), 2.0 * frame.radii, rtol=1e-6)
        np.testing.assert_allclose(np.array(particles.GetVelocitiesAttr().Get(t)), frame.velocities,
                                   rtol=1e-6, atol=1e-7)
        np.testing.assert_array_equal(np.array(particles.GetIdsAttr().Get(t)), frame.ids)

    ball, drum = (stage.GetPrimAtPath(f"/World/bodies/body_{k}") for k in (0, 1))
    # the crate of the first run's frame 5 is gone; body_1 is the second run's drum
    assert stage.GetPrimAtPath("/World/bodies/body_1/shape").GetTypeName() == "Cylinder"
    ball_op, drum_op = (UsdGeom.Xformable(p).GetOrderedXformOps() for p in (ball, drum))
    assert len(ball_op) == len(drum_op) == 1
    assert ball_op[0].GetTimeSamples() == [2.0, 3.0, 4.0, 6.0]
    assert drum_op[0].GetTimeSamples() == [6.0]
    sources = {0: None, 1: None, 2: first[2], 3: first[3], 4: second[0], 5: None, 6: second[2]}
    for t, frame in sources.items():
        if frame is not None:
            local = ball_op[0].GetOpTransform(t)
            expected = export.usd_matrix(frame.bodies[0].shape_rotation, frame.bodies[0].shape_center)
            assert Gf.IsClose(local, expected, 1e-12), t
    seen = [UsdGeom.Imageable(ball).ComputeVisibility(t) for t in range(7)]
    assert seen == ["invisible", "invisible", "inherited", "inherited", "inherited", "invisible", "inherited"]
    assert UsdGeom.Imageable(ball).GetVisibilityAttr().GetTimeSamples() == [float(t) for t in range(7)]
    seen = [UsdGeom.Imageable(drum).ComputeVisibility(t) for t in range(7)]
    assert seen == ["invisible"] * 6 + ["inherited"]


def test_a_continued_layer_is_the_layer_one_recorder_would_have_written(tmp_path):
    pytest.importorskip("pxr")
    first, second = first_run(), second_run()
    recorded(tmp_path / "resumed.usda", first)
    recorded(tmp_path / "resumed.usda", second, keep_until=3)
    recorded(tmp_path / "straight.usda", first[:4] + second)
    assert (tmp_path / "resumed.usda").read_text() == (tmp_path / "straight.usda").read_text()


@pytest.mark.parametrize("keep_until, kept", [(0, [0.0]), (1, [0.0, 1.0]), (4, [0.0, 1.0, 2.0, 3.0, 4.0]),
                                              (5, [float(t) for t in range(6)]), (99, [float(t) for t in range(6)])])
def test_keep_until_keeps_what_one_recorder_adding_those_frames_would_have(tmp_path, keep_until, kept):
    pytest.importorskip("pxr")
    first = first_run()
    recorded(tmp_path / "run.usda", first)
    resumed = recorded(tmp_path / "run.usda", [], keep_until=keep_until)
    assert resumed.time_codes == kept
    # a body present in every kept frame gets no visibility samples; one first seen later is not there
    recorded(tmp_path / "straight.usda", first[:len(kept)])
    assert (tmp_path / "run.usda").read_text() == (tmp_path / "straight.usda").read_text()
    # and it goes on like one: a frame added again replaces the kept one
    again = make_frame(4, frame=int(kept[-1]), seed=77, bodies=[pose(tc.Sphere(radius=0.1), seed=78)])
    recorded(tmp_path / "run.usda", [again], keep_until=keep_until)
    recorded(tmp_path / "straight.usda", first[:len(kept)] + [again])
    assert (tmp_path / "run.usda").read_text() == (tmp_path / "straight.usda").read_text()


def test_keep_until_refuses_a_layer_at_another_rate_or_not_its_own_and_leaves_it(tmp_path):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    path = tmp_path / "run.usdc"
    with UsdRecorder(path, 30.0) as recorder:
        for k in range(3):
            recorder.add(dataclasses.replace(make_frame(2, frame=k), frame_rate=30.0))
    before = path.read_bytes()
    with pytest.raises(ValueError, match=r"cannot continue the USD layer '.*run\.usdc'.*timeCodesPerSecond is 30\.0, "
                                         r"not this recorder's frame_rate 24\.0"):
        UsdRecorder(path, FPS, keep_until=1)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["run.usdc"]

    foreign = tmp_path / "other.usda"
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Xform.Define(stage, "/World/particles")  # not Points
    stage.GetRootLayer().Export(str(foreign))
    text = foreign.read_text()
    with pytest.raises(ValueError, match=r"'.*other\.usda'.*no /World/particles Points prim"):
        UsdRecorder(foreign, FPS, keep_until=1)
    garbage = tmp_path / "garbage.usda"
    garbage.write_text("not a layer")
    with pytest.raises(ValueError, match=r"'.*garbage\.usda'.*USD cannot read it"):
        UsdRecorder(garbage, FPS, keep_until=1)
    assert foreign.read_text() == text and garbage.read_text() == "not a layer"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["garbage.usda", "other.usda", "run.usdc"]
    # without keep_until the file is not read: a new layer replaces it at save()
    UsdRecorder(garbage, FPS).save()
    stage = open_fresh(garbage)
    assert stage.GetPrimAtPath("/World/particles").IsA(UsdGeom.Points)


def test_keep_until_without_a_file_starts_a_new_layer(tmp_path):
    pytest.importorskip("pxr")
    frames = first_run()[:3]
    recorder = recorded(tmp_path / "resumed.usda", frames, keep_until=3)
    assert recorder.time_codes == [0.0, 1.0, 2.0]
    recorded(tmp_path / "new.usda", frames)
    assert (tmp_path / "resumed.usda").read_text() == (tmp_path / "new.usda").read_text()


@pytest.mark.parametrize("value, error, message", [
    (-1, ValueError, "keep_until must be >= 0; got -1"),
    (3.0, TypeError, "keep_until must be an integer; got 3.0"),
    ("3", TypeError, "keep_until must be an integer; got '3'"),
    (True, TypeError, "keep_until must be an integer; got True"),
])
def test_bad_keep_until_is_refused(tmp_path, value, error, message):
    pytest.importorskip("pxr")
    recorded(tmp_path / "run.usda", first_run())
    before = (tmp_path / "run.usda").read_bytes()
    with pytest.raises(error, match=message):
        UsdRecorder(tmp_path / "run.usda", FPS, keep_until=value)
    with pytest.raises(TypeError):
        UsdRecorder(tmp_path / "run.usda", FPS, 3)  # keyword only
    assert (tmp_path / "run.usda").read_bytes() == before
    assert UsdRecorder(tmp_path / "run.usda", FPS, keep_until=np.int64(2)).time_codes == [0.0, 1.0, 2.0]


def test_a_body_missing_only_after_keep_until_is_left_with_no_visibility_samples(tmp_path):
    pytest.importorskip("pxr")
    from pxr import UsdGeom

    ball = tc.Sphere(radius=0.1)
    frames = [make_frame(2, frame=k, seed=k, bodies=[pose(ball, seed=k)] if k != 4 else []) for k in range(6)]
    recorded(tmp_path / "run.usda", frames)
    recorded(tmp_path / "run.usda", [], keep_until=3)
    recorded(tmp_path / "straight.usda", frames[:4])
    assert (tmp_path / "run.usda").read_text() == (tmp_path / "straight.usda").read_text()
    stage = open_fresh(tmp_path / "run.usda")
    body = UsdGeom.Imageable(stage.GetPrimAtPath("/World/bodies/body_0"))
    assert not body.GetVisibilityAttr().IsAuthored()
    # missing again after the resume: hidden there only
    resumed = recorded(tmp_path / "run.usda", [make_frame(2, frame=4, seed=9)], keep_until=3)
    assert resumed.time_codes == [0.0, 1.0, 2.0, 3.0, 4.0]
    stage = open_fresh(tmp_path / "run.usda")
    body = UsdGeom.Imageable(stage.GetPrimAtPath("/World/bodies/body_0"))
    assert [body.ComputeVisibility(t) for t in range(5)] == ["inherited"] * 4 + ["invisible"]


def test_keep_until_before_every_recorded_frame_leaves_a_new_layer(tmp_path):
    pytest.importorskip("pxr")
    frames = [make_frame(2, frame=k, seed=k, bodies=[pose(tc.Sphere(radius=0.1), seed=k)]) for k in (5, 6)]
    recorded(tmp_path / "run.usda", frames)
    assert recorded(tmp_path / "run.usda", [], keep_until=4).time_codes == []
    UsdRecorder(tmp_path / "new.usda", FPS).save()
    assert (tmp_path / "run.usda").read_text() == (tmp_path / "new.usda").read_text()


def test_a_frame_added_again_without_a_body_stays_without_it_when_continued(tmp_path):
    pytest.importorskip("pxr")
    from pxr import UsdGeom

    ball = tc.Sphere(radius=0.1)
    # frame 2 added again without the ball: its transform sample at 2 stays, hidden there
    frames = [make_frame(2, frame=k, seed=k, bodies=[pose(ball, seed=k)]) for k in range(5)]
    frames.append(make_frame(3, frame=2, seed=12))
    recorded(tmp_path / "run.usda", frames)
    resumed = recorded(tmp_path / "run.usda", [make_frame(2, frame=4, seed=14, bodies=[pose(ball, seed=4)])],
                       keep_until=3)
    assert resumed._bodies[0][1] == {0.0, 1.0, 3.0, 4.0}  # where the ball is
    recorded(tmp_path / "straight.usda", frames[:4] + frames[5:] + [make_frame(2, frame=4, seed=14,
                                                                             bodies=[pose(ball, seed=4)])])
    assert (tmp_path / "run.usda").read_text() == (tmp_path / "straight.usda").read_text()
    stage = open_fresh(tmp_path / "run.usda")
    body = UsdGeom.Imageable(stage.GetPrimAtPath("/World/bodies/body_0"))
    assert [body.ComputeVisibility(t) for t in range(5)] == ["inherited"] * 2 + ["invisible"] + ["inherited"] * 2


def test_a_one_frame_usd_also_holds_the_frame_as_default_values(tmp_path):
    pxr = pytest.importorskip("pxr")
    frame = make_frame(6, frame=12)
    export.save_frame(tmp_path / "one.usd", frame)
    stage = pxr.Usd.Stage.Open(str(tmp_path / "one.usd"))
    points = pxr.UsdGeom.Points(stage.GetPrimAtPath("/World/particles"))
    for time in (pxr.Usd.TimeCode.Default(), 12.0):  # a reader asking with or without a time code
        assert np.allclose(np.array(points.GetPointsAttr().Get(time)), frame.positions, atol=1e-6)
        assert np.allclose(np.array(points.GetWidthsAttr().Get(time)), 2 * frame.radii)
        assert list(points.GetIdsAttr().Get(time)) == frame.ids.tolist()
