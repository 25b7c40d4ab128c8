"""Values and calls that used to crash deep inside Taichi, or to corrupt the state silently,
get one clear error that names the argument, before any kernel runs (issue 25).

The session runs in f64 (conftest.py). The f32 range rule is checked here under
`f32_rules`, which makes validation read an f32 runtime while Taichi keeps running in f64
(nothing reaches a kernel), and once for real in a child process with its own f32 Taichi,
which also restarts Taichi under a scene built before.
"""

import dataclasses
import json
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import taichi as ti

import tai_coll as tc
from tai_coll import runtime
from tai_coll.geometry import implicit_eval
from test_validation import no_kernels, scene  # noqa: F401 (fixtures: kernels raise KernelRan; two particles)

vec3 = ti.math.vec3
F32_MAX = float(np.finfo(np.float32).max)
F32_TINY = float(np.finfo(np.float32).tiny)


@pytest.fixture
def f32_rules(monkeypatch):
    """Validation as under tc.init(precision="f32"), on the session's running Taichi."""
    monkeypatch.setattr(runtime, "_info", dataclasses.replace(runtime.info(), precision="f32"))


# ---------------------------------------------------------------------------- the float range

@pytest.mark.parametrize("call, name", [
    (lambda s: tc.Scene(gravity=(0.0, 1e39, 0.0)), "gravity"),
    (lambda s: tc.Scene(dt=1e-50), "dt"),
    (lambda s: tc.Scene(dt=1e39), "dt"),
    (lambda s: setattr(s, "gravity", (0.0, -1e39, 0.0)), "gravity"),
    (lambda s: s.add_particles(positions=[[0.0, 1e39, 0.0]]), "positions"),
    (lambda s: s.add_particles(positions=[[0.0, 0.0, 0.0], [-1e39, 0.0, 0.0]]), "positions"),
    (lambda s: s.add_particles(positions=np.zeros((1, 3)), velocities=[[0.0, 0.0, 1e39]]), "velocities"),
    (lambda s: s.add_particles(positions=np.zeros((1, 3)), mass=1e-50), "mass"),
    (lambda s: s.add_particles(positions=np.zeros((1, 3)), mass=1e39), "mass"),
    (lambda s: s.add_particles(positions=np.zeros((2, 3)), radius=[0.01, 1e-45]), "radius"),
    (lambda s: s.add_particles(positions=np.zeros((1, 3)), radius=1e-50), "radius"),
    (lambda s: s.set_positions([[0.0, 0.0, 0.0], [0.0, 1e39, 0.0]]), "positions"),
    (lambda s: s.set_velocities([[0.0, 0.0, 0.0], [0.0, -1e39, 0.0]]), "velocities"),
    (lambda s: s.set_angular_velocities([[0.0, 0.0, 0.0], [1e39, 0.0, 0.0]]), "angular_velocities"),
    (lambda s: s.add_collider(tc.Plane(), velocity=(1e39, 0.0, 0.0)), "velocity"),
    (lambda s: tc.Plane(point=(0.0, 1e39, 0.0)), "point"),
    (lambda s: tc.Sphere(center=(1e39, 0.0, 0.0)), "center"),
    (lambda s: tc.Sphere(radius=1e-50), "radius"),
    (lambda s: tc.Box(half_extents=(1e39, 1.0, 1.0)), "half_extents"),
    (lambda s: tc.Capsule(half_height=1e-40), "half_height"),
    (lambda s: tc.Material(friction=1e39), "friction"),
    (lambda s: tc.Material(wet_friction=1e-50), "wet_friction"),
    (lambda s: tc.Material(restitution=1e-45), "restitution"),
    (lambda s: tc.Sphere().signed_distance([[0.0, 1e39, 0.0]]), "points"),
    (lambda s: tc.Implicit(lambda p: 1e39 * np.linalg.norm(p, axis=1), bounds=((-1, -1, -1), (1, 1, 1)),
                           resolution=8), "function values"),
    (lambda s: tc.HeightField(heights=[[0.0, 0.0], [0.0, 1e39]], cell_size=0.1), "heights"),
    (lambda s: tc.collide_pair([1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], 1e-50, 1.0), "mass_a"),
    (lambda s: tc.collide_pair([1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], 1.0, 1e39), "mass_b"),
    (lambda s: tc.TriangleMesh(mesh=([[0.0, 0.0, 0.0], [1e39, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0, 1, 2]])),
     "mesh vertices"),
])
def test_values_f32_cannot_hold_are_refused_naming_the_argument(scene, call, name, f32_rules, no_kernels):
    before = scene.positions(), scene.velocities()
    with pytest.raises(ValueError, match=rf"^{name}.* must be within the range f32 holds"):
        call(scene)
    assert scene.num_particles == 2
    np.testing.assert_array_equal(scene.positions(), before[0])
    np.testing.assert_array_equal(scene.velocities(), before[1])
    np.testing.assert_array_equal(scene.gravity, [0.0, -9.81, 0.0])


def test_the_range_message_states_the_range_and_what_would_be_stored(scene, f32_rules, no_kernels):
    with pytest.raises(ValueError, match=r"mass must be within the range f32 holds \(0, or magnitudes 1\.175e-38 to "
                                         r"3\.403e\+38\); got 1e-50 \(index 0\), which would be stored as 0"):
        scene.add_particles(positions=np.zeros((1, 3)), mass=1e-50)
    with pytest.raises(ValueError, match=r"positions .*\(magnitudes up to 3\.403e\+38\); got 1e\+39 \(row 1\), "
                                         r"which would be stored as inf; tc.init\(precision='f64'\) holds more"):
        scene.add_particles(positions=[[0.0, 0.0, 0.0], [0.0, 1e39, 0.0]])


def test_values_f32_holds_are_kept(scene, f32_rules):
    """The neighbours that are fine: the extremes f32 holds, zeros, and coordinates below its
    smallest normal number (stored as 0, an error below what f32 resolves; velocities that
    decay frame after frame must not start failing when written back)."""
    sl = scene.add_particles(positions=[[0.0, 1e38, -1e38], [0.0, 1e-40, 0.0]], velocities=[[0.0, 0.0, 0.0]] * 2,
                             mass=[F32_TINY, 1e38], radius=[1e-37, 0.01])
    assert (sl.start, sl.stop) == (2, 4)
    scene.set_velocities(np.full((4, 3), 1e-42))
    scene.gravity = (0.0, -1e-40, 0.0)
    tc.Scene(dt=F32_TINY)
    tc.Sphere(radius=3e38)
    tc.Material(friction=0.0, wet_friction=1e-30)


def test_f64_holds_what_f32_cannot_and_refuses_its_own_extremes(scene):
    scene.add_particles(positions=[[0.0, 1e39, 0.0]], mass=1e-50, radius=1e-50)
    assert scene.num_particles == 3 and scene.masses()[2] == 1e-50
    tc.Sphere(radius=1e39)
    # below f64's smallest normal number: the range rule, or "> 0" where the CPU already
    # reads such a number as 0 (Taichi sets the flush-to-zero modes in this process)
    with pytest.raises(ValueError, match=r"^radius must be (within the range f64 holds|> 0)"):
        tc.Sphere(radius=1e-310)
    with pytest.raises(ValueError, match=r"^mass must be (within the range f64 holds|> 0)"):
        scene.add_particles(positions=np.zeros((1, 3)), mass=1e-320)


def test_before_init_values_are_held_to_f32_the_default(monkeypatch, no_kernels):
    """Before tc.init the rule reads f32, the precision first use starts, and starts nothing."""
    monkeypatch.setattr(runtime, "_info", None)
    with pytest.raises(ValueError, match="^radius must be within the range f32 holds"):
        tc.Sphere(radius=1e-50)
    assert runtime.info() is None


# ---------------------------------------------------------------------------- non-real numbers

@pytest.mark.parametrize("call, error, name", [
    (lambda s: s.add_particles(positions=np.array([[1 + 1j, 0.0, 0.0]])), TypeError, "positions"),
    (lambda s: s.add_particles(positions=[[0.0, 0.0, 0.0]], velocities=[[0.0, 2j, 0.0]]), TypeError, "velocities"),
    (lambda s: s.add_particles(positions=[[0.0, 0.0, 0.0]], mass=1 + 0j), TypeError, "mass"),
    (lambda s: s.add_particles(positions=[[0.0, 0.0, 0.0]], radius=np.array([0.01 + 0j])), TypeError, "radius"),
    (lambda s: s.add_particles(positions=[[True, False, True]]), TypeError, "positions"),
    (lambda s: s.add_particles(positions=[["0", "1", "2"]]), TypeError, "positions"),
    (lambda s: s.add_particles(positions=[[0, 10**400, 0]]), ValueError, "positions"),
    (lambda s: s.set_positions(np.zeros((2, 3), dtype=complex)), TypeError, "positions"),
    (lambda s: s.set_velocities(np.zeros((2, 3), dtype=np.complex64)), TypeError, "velocities"),
    (lambda s: tc.Scene(gravity=(0.0, -9.81 + 1j, 0.0)), TypeError, "gravity"),
    (lambda s: tc.Scene(dt=10**400), ValueError, "dt"),
    (lambda s: tc.Sphere(center=np.array([0, 0, 1j])), TypeError, "center"),
    (lambda s: tc.Box(rotation=np.eye(3, dtype=complex)), TypeError, "rotation"),
    (lambda s: tc.Sphere().signed_distance(np.zeros((2, 3), dtype=complex)), TypeError, "points"),
])
def test_complex_and_other_non_real_input_is_refused_not_cast(scene, call, error, name, no_kernels):
    with pytest.raises(error, match=f"^{name}"):
        call(scene)
    assert scene.num_particles == 2


# ---------------------------------------------------------------------------- tc.init

def test_the_limits_of_init_are_taichis(no_kernels):
    """threads and seed at their limits pass the checks; one past them does not, and the
    runtime is left as it was (tests/test_validation.py has the rest)."""
    runtime._check_init_args("cpu", "f64", runtime.MAX_THREADS, runtime.MAX_SEED)
    before = runtime.info()
    with pytest.raises(ValueError, match=r"seed must be an integer from 0 to 2147483647"):
        tc.init(arch="cpu", precision="f64", threads=2, seed=runtime.MAX_SEED + 1)
    assert runtime.info() is before


# ---------------------------------------------------------------------------- a scene of an old runtime

SCENE_CALLS = {
    "add_collider": lambda s: s.add_collider(tc.Plane()),
    "add_body": lambda s: s.add_body(tc.Sphere(radius=0.1), mass=1.0),
    "add_particles": lambda s: s.add_particles(positions=[[0.0, 0.0, 0.0]]),
    "enable_particle_collisions": lambda s: s.enable_particle_collisions(),
    "particle_overlap": lambda s: s.particle_overlap(),
    "state_nbytes": lambda s: s.state_nbytes(),
    "step": lambda s: s.step(),
    "positions": lambda s: s.positions(),
    "velocities": lambda s: s.velocities(),
    "angular_velocities": lambda s: s.angular_velocities(),
    "masses": lambda s: s.masses(),
    "radii": lambda s: s.radii(),
    "particle_status": lambda s: s.particle_status(),
    "sleeping": lambda s: s.sleeping(),
    "status": lambda s: s.status(),
    "stats": lambda s: s.stats(),
    "set_positions": lambda s: s.set_positions(np.zeros((2, 3))),
    "set_velocities": lambda s: s.set_velocities(np.zeros((2, 3))),
    "set_angular_velocities": lambda s: s.set_angular_velocities(np.zeros((2, 3))),
    "add_emitter": lambda s: s.add_emitter(tc.Sphere(radius=0.1), rate=10.0),
    "add_sink": lambda s: s.add_sink(tc.Box()),
    "ids": lambda s: s.ids(),
    "frame_data": lambda s: s.frame_data(),
    "save_frame": lambda s: s.save_frame("never_written.npz"),
    "save_state": lambda s: s.save_state("never_written.npz"),
    "load_state": lambda s: s.load_state("never_written.npz"),
    "gravity =": lambda s: setattr(s, "gravity", (0.0, 0.0, 0.0)),
}


def test_every_public_scene_method_is_guarded():
    """The table above covers the whole public surface, each method wrapped by the one guard."""
    methods = {name for name, member in vars(tc.Scene).items()
               if not name.startswith("_") and callable(member)}
    assert methods == {name for name in SCENE_CALLS if not name.endswith("=")}
    for name in methods:
        assert getattr(tc.Scene, name).__wrapped__, name
    assert tc.Scene.gravity.fset.__wrapped__


@pytest.mark.parametrize("name", list(SCENE_CALLS))
def test_a_scene_of_an_old_runtime_refuses_every_public_call(scene, name, no_kernels):
    # what tc.init with other arguments leaves behind: a scene of an earlier generation
    scene._runtime = dataclasses.replace(scene._runtime, generation=scene._runtime.generation - 1)
    with pytest.raises(RuntimeError, match="this Scene was built before tai_coll.init.. restarted Taichi"):
        SCENE_CALLS[name](scene)
    # its host-side attributes still read, so it prints
    assert scene.num_particles == 2 and scene.time == 0.0 and "2 particles" in repr(scene)


def test_particle_collisions_of_an_old_runtime_refuse_their_calls_and_counters(scene, no_kernels):
    pairs = scene.enable_particle_collisions()
    pairs._runtime = dataclasses.replace(pairs._runtime, generation=pairs._runtime.generation - 1)
    for call in (lambda: pairs.neighbour_overflow, lambda: pairs.history_overflow, lambda: pairs.arrays()):
        with pytest.raises(RuntimeError, match="this ParticleCollisions was built before tai_coll.init"):
            call()
    assert "ParticleCollisions(" in repr(pairs)  # host-side state still prints


RESTART = textwrap.dedent("""
    import json
    import numpy as np
    import tai_coll as tc

    tc.init(arch="cpu", threads=1)   # f32
    out = {}
    def attempt(key, call):
        try:
            call()
            out[key] = "ok"
        except Exception as error:
            out[key] = f"{type(error).__name__}: {error}"

    scene = tc.Scene(dt=1e-3, substeps=2)
    scene.add_particles(positions=[[0.0, 1.0, 0.0]], radius=0.01)
    attempt("gravity", lambda: tc.Scene(gravity=(0.0, 1e39, 0.0)))
    attempt("mass", lambda: scene.add_particles(positions=[[0.0, 0.0, 0.0]], mass=1e-50))
    attempt("velocities", lambda: scene.set_velocities([[0.0, 1e39, 0.0]]))
    attempt("seed", lambda: tc.init(arch="cpu", threads=1, seed=2**64))
    attempt("step after a refused init", lambda: scene.step())
    out["masses"] = scene.masses().tolist()
    tc.init(arch="cpu", threads=1, seed=2**31 - 1)   # a restart, at the largest seed
    for name in ("positions", "particle_status", "particle_overlap", "step"):
        attempt(name, getattr(scene, name))
    attempt("set_positions", lambda: scene.set_positions([[0.0, 2.0, 0.0]]))
    fresh = tc.Scene()
    fresh.add_particles(positions=[[0.0, 1.0, 0.0]])
    fresh.step()
    out["fresh"] = fresh.positions().tolist()
    print(json.dumps(out))
""")


@pytest.mark.slow  # a child process with its own Taichi
def test_f32_range_and_a_restart_in_a_real_f32_runtime():
    done = subprocess.run([sys.executable, "-c", RESTART], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["gravity"].startswith("ValueError: gravity must be within the range f32 holds")
    assert out["mass"].startswith("ValueError: mass must be within the range f32 holds")
    assert out["velocities"].startswith("ValueError: velocities must be within the range f32 holds")
    assert out["seed"].startswith("ValueError: seed must be an integer from 0 to")
    assert out["step after a refused init"] == "ok"  # the refused init left the runtime running
    assert out["masses"] == [1.0]
    for name in ("positions", "particle_status", "particle_overlap", "step", "set_positions"):
        assert out[name].startswith("RuntimeError: this Scene was built before tai_coll.init() restarted"), name
    assert out["fresh"][0][1] < 1.0


# ---------------------------------------------------------------------------- Scene odds and ends

@pytest.mark.parametrize("solver", [tc.ImpulseSolver, tc.PenaltySolver])
def test_a_solver_class_is_refused_asking_for_an_instance(solver, no_kernels):
    with pytest.raises(TypeError, match=rf"^solver must be a solver instance.*pass an instance, {solver.__name__}\("):
        tc.Scene(solver=solver)


def test_particle_overlap_of_an_empty_scene_is_zero(no_kernels):
    empty = {"max": 0.0, "mean": 0.0, "pairs": 0}
    assert tc.Scene().particle_overlap() == empty
    with_pairs = tc.Scene()
    with_pairs.enable_particle_collisions()
    assert with_pairs.particle_overlap() == empty


# ---------------------------------------------------------------------------- tc.Implicit

@ti.func
def pointing(p: vec3):
    return p * 2.0


@ti.func
def two_values(p: vec3):
    return p.x, p.y


@ti.func
def no_value(p: vec3):
    q = p  # noqa: F841 (returns nothing)


@ti.func
def misspelt(p: vec3):
    return p.norm() - radius_of_the_ball  # noqa: F821 (the typo under test)


@ti.func
def ball(p: vec3):
    return p.norm() - 1.0


@ti.func
def scalar_gradient(p: vec3):
    return p.norm()


@pytest.mark.parametrize("function, gradient, match", [
    (pointing, None, "^function pointing must return one float.*it returns vec3"),
    (two_values, None, "^function two_values must return one float.*it returns a tuple of 2 values"),
    (no_value, None, "^function no_value must return one float.*it returns nothing"),
    (misspelt, None, "(?s)^function misspelt must be a Taichi function .*radius_of_the_ball"),
    (ball, scalar_gradient, "^gradient scalar_gradient must return a vec3.*it returns float"),
])
def test_a_taichi_function_of_the_wrong_kind_is_refused_at_construction(function, gradient, match):
    registered = len(implicit_eval._REGISTERED)
    with pytest.raises(TypeError, match=match):
        tc.Implicit(function, gradient=gradient)
    assert len(implicit_eval._REGISTERED) == registered  # took no collider kind


@pytest.mark.parametrize("options, name", [
    (dict(resolution=100000), "resolution"),
    (dict(resolution=257), "resolution"),
    (dict(voxel_size=1e-30), "voxel_size"),  # would wrap around an integer count
    (dict(voxel_size=2.0 / 300), "voxel_size"),
])
def test_an_implicit_grid_is_capped_as_meshsdf_is(options, name, no_kernels):
    from tai_coll.geometry import grid_sdf

    assert grid_sdf.MAX_NODES == 256 ** 3  # (MeshSDF counts its nodes with the same grid_sdf.node_counts)
    calls = []

    def sphere(points):
        calls.append(len(points))
        return np.linalg.norm(points, axis=1) - 0.5

    with pytest.raises(ValueError, match=rf"^{name}: the grid would have .* more than 16,777,216"):
        tc.Implicit(sphere, bounds=((-1, -1, -1), (1, 1, 1)), **options)
    assert calls == []  # refused before sampling
    assert tc.Implicit(sphere, bounds=((-1, -1, -1), (1, 1, 1)), resolution=16).values.shape == (16,) * 3


@pytest.mark.parametrize("options, name", [
    (dict(resolution=100000), "resolution"),
    (dict(voxel_size=1e-30), "voxel_size"),  # wrapped around an integer count to a 2 x 2 x 2 grid
    (dict(voxel_size=1.0 / 300), "voxel_size"),
])
def test_a_mesh_grid_beyond_the_node_cap_is_refused_naming_the_argument(options, name, no_kernels):
    import trimesh

    with pytest.raises(ValueError, match=rf"^{name}: the grid would have .* more than 16,777,216"):
        tc.MeshSDF(trimesh.creation.box(extents=(1.0, 1.0, 1.0)), **options)


# ---------------------------------------------------------------------------- mesh files

MESH_LOADERS = {"MeshSDF": tc.MeshSDF, "TriangleMesh": tc.TriangleMesh, "bake_mesh": tc.bake_mesh}


@pytest.mark.parametrize("load", list(MESH_LOADERS))
def test_a_file_trimesh_cannot_parse_names_the_argument_and_the_file(load, tmp_path, no_kernels):
    noise = tmp_path / "noise.stl"
    noise.write_bytes(np.random.default_rng(0).integers(0, 256, 2000, dtype=np.uint8).tobytes())
    text = tmp_path / "text.obj"
    text.write_text("this is not a mesh\n")
    unknown = tmp_path / "mesh.unknown"
    unknown.write_text("1 2 3\n")
    # Random bytes: trimesh raises, or (with a text-encoding detector installed, such as
    # charset-normalizer, which Ray's dependencies bring) decodes them as an ASCII STL of no
    # triangles. Either way the error names the argument and the file.
    with pytest.raises(ValueError, match=f"^mesh: (could not read a mesh from|the mesh read from) "
                                         f"{re.escape(repr(str(noise)))}"):
        MESH_LOADERS[load](noise)
    with pytest.raises(ValueError, match=f"^mesh: could not read a mesh from {re.escape(repr(str(unknown)))}"):
        MESH_LOADERS[load](unknown)
    with pytest.raises(ValueError, match=f"^mesh: the mesh read from {re.escape(repr(str(text)))} is empty"):
        MESH_LOADERS[load](text)
    with pytest.raises(FileNotFoundError, match="mesh file not found"):
        MESH_LOADERS[load](tmp_path / "missing.stl")
    with pytest.raises(ValueError, match=f"^mesh: {re.escape(repr(str(tmp_path)))} is not a file"):
        MESH_LOADERS[load](tmp_path)


def test_particle_collisions_refuse_more_particles_than_their_lists_can_index(monkeypatch):
    # Taichi 1.7 computes an array element's offset in 32-bit integers: neighbour lists of
    # NEIGHBOUR_CAPACITY ints a particle index at most MAX_LISTED particles. A scene with pairs
    # refuses more, naming the argument, before anything is stored; shown with the limit
    # lowered to 100 (the real one needs some GB).
    from tai_coll.neighbors.hash_grid import MAX_LISTED, NEIGHBOUR_CAPACITY

    assert MAX_LISTED * NEIGHBOUR_CAPACITY <= 2**31 - 1 < (MAX_LISTED + 1) * NEIGHBOUR_CAPACITY
    monkeypatch.setattr("tai_coll.scene.scene.MAX_LISTED", 100)
    lattice = np.stack(np.meshgrid(*[np.arange(5) * 0.02] * 3, indexing="ij"), -1).reshape(-1, 3)  # 125

    crowded = tc.Scene()
    crowded.add_particles(positions=lattice, radius=0.005)
    with pytest.raises(ValueError, match=r"particle collisions hold at most 100 particles.*has 125"):
        crowded.enable_particle_collisions(material=tc.Material())
    assert crowded.particle_collisions is None

    scene = tc.Scene()
    scene.add_particles(positions=lattice[:60], radius=0.005)
    scene.enable_particle_collisions(material=tc.Material())
    with pytest.raises(ValueError, match=r"^positions: .* at most 100 particles .* has 60, and 41 more"):
        scene.add_particles(positions=lattice[60:101] + 1.0, radius=0.005)
    assert scene.num_particles == 60
    scene.add_particles(positions=lattice[60:100] + 1.0, radius=0.005)  # up to the limit
    scene.step(1)
    assert scene.num_particles == 100 and np.all(np.isfinite(scene.positions()))


def test_a_scene_refuses_more_particles_than_its_arrays_can_index(monkeypatch):
    # Taichi 1.7's 32-bit offsets count the scalars of vector elements (a 6-vector array's element
    # 357,913,941 lies past 2**31 - 1: on the CPU it crashed, measured). The widest arrays a
    # particle has (the kept plane, the bodies' ledger of two 3-vectors) fix the store's limit:
    # every per-particle array of a scene with a body, an emitter and spin stays within it.
    from tai_coll.scene import particles as store_module

    limit = store_module.MAX_STORED
    assert limit * store_module.SEPARATION_SIZE <= 2**31 - 1 < (limit + 1) * store_module.SEPARATION_SIZE
    wide = tc.Scene()
    wide.add_collider(tc.Plane())
    wide.add_body(tc.Box(half_extents=(0.05, 0.05, 0.05), center=(0, 0.2, 0)), density=500.0)
    wide.add_emitter(tc.Box(half_extents=(0.05, 0.01, 0.05), center=(0, 0.5, 0)), rate=2000.0, radius=0.004)
    wide.add_particles(positions=np.random.default_rng(0).uniform(0.1, 0.3, (50, 3)), radius=0.004)
    wide.step(2)
    store = wide._particles
    store.enable_spin()  # (the angular velocities, and their second set)
    held = store.arrays() + wide._bodies.coupling.arrays()
    assert len(store.arrays()) > len(store_module.STORED) and wide._bodies.coupling.arrays()
    for array in held:
        values = array.to_numpy()
        assert values.size <= store_module.SEPARATION_SIZE * store.capacity, (array.shape, values.shape)

    # shown with the limit lowered to 3,000 (the real one needs tens of GB): the store's growth
    # stops at the limit, and an addition past it is refused before anything is stored
    monkeypatch.setattr(store_module, "MAX_STORED", 3000)
    scene = tc.Scene()
    scene.add_particles(positions=np.random.default_rng(1).uniform(0, 1, (2000, 3)), radius=0.001)
    assert scene._particles.capacity == 2048
    scene.add_particles(positions=np.random.default_rng(2).uniform(0, 1, (900, 3)), radius=0.001)
    assert scene._particles.capacity == 3000 and scene.num_particles == 2900
    with pytest.raises(ValueError, match=r"^positions: a scene holds at most 3,000 particles .* has 2,900, "
                                         r"and 101 more would pass it"):
        scene.add_particles(positions=np.zeros((101, 3)), radius=0.001)
    assert scene.num_particles == 2900 and scene._particles.capacity == 3000
    scene.add_particles(positions=np.random.default_rng(3).uniform(0, 1, (100, 3)), radius=0.001)
    scene.step(1)
    assert scene.num_particles == 3000 and np.all(np.isfinite(scene.positions()))
