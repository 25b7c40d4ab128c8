"""The production workflow (docs/physics.md 8): emitters and sinks, stable ids, frame export
through the scene, and save_state / load_state continuing a run bit for bit."""

import subprocess
import sys
import warnings

import numpy as np
import pytest

import tai_coll as tc
from conftest import FLOOR

FPS = 60.0


def pairwise_gaps(x, r):
    """Distance minus the sum of radii of every pair (n small)."""
    d = np.linalg.norm(x[:, None] - x[None], axis=2) - (r[:, None] + r[None])
    return d[np.triu_indices(len(x), 1)]


def still_scene(**options):
    """No gravity, no collisions: particles stay where they are placed."""
    return tc.Scene(gravity=(0.0, 0.0, 0.0), **options)


# ---------------------------------------------------------------- emitters
def test_an_emitter_at_3000_per_second_for_half_a_second_adds_1500_particles_none_overlapping():
    scene = still_scene()
    emitter = scene.add_emitter(tc.Box(center=(0.0, 0.5, 0.0), half_extents=(0.1, 0.1, 0.1)), rate=3000.0,
                                radius=0.005, mass=0.002, velocity=(0.0, 0.0, 0.0))
    scene.step(30)  # 0.5 s at 60 frames a second
    assert scene.time == pytest.approx(0.5)
    assert scene.num_particles == emitter.emitted == 1500 and emitter.skipped == 0
    ids = scene.ids()
    assert ids.dtype == np.int64 and np.array_equal(ids, np.arange(1500))  # unique, ascending, insertion order
    x, r = scene.positions(), scene.radii()
    assert pairwise_gaps(x, r).min() >= 0.0
    assert np.all(np.abs(x - (0.0, 0.5, 0.0)) <= 0.1 + 1e-12)  # centres in the region
    assert np.all(scene.masses() == 0.002) and np.all(r == 0.005)
    assert scene.stats()["emitted"] == 1500 and scene.stats()["emission_skipped"] == 0


def test_emission_follows_start_stop_and_max_particles_and_gives_the_velocity():
    scene = still_scene()
    a = scene.add_emitter(tc.Sphere(center=(0.0, 0.0, 0.0), radius=0.2), rate=600.0, start=0.1, stop=0.2,
                          velocity=(0.0, 0.0, 0.0), radius=0.004)
    b = scene.add_emitter(tc.Cylinder(center=(1.0, 0.0, 0.0), radius=0.1, half_height=0.2), rate=6000.0,
                          max_particles=25, velocity=(0.0, 0.0, 0.0), radius=0.004)
    scene.step(3)  # to t = 0.05: a not started; b capped at 25
    assert (a.emitted, b.emitted) == (0, 25)
    scene.step(9)  # to t = 0.2
    assert (a.emitted, b.emitted) == (60, 25)
    scene.step(6)
    assert a.emitted == 60 and scene.num_particles == 85
    x = scene.positions()
    in_b = x[:25] - (1.0, 0.0, 0.0)
    assert np.all(np.hypot(in_b[:, 0], in_b[:, 2]) <= 0.1 + 1e-12) and np.all(np.abs(in_b[:, 1]) <= 0.2 + 1e-12)
    # (b's first, in its cylinder; a's, in its ball)
    assert np.all(np.linalg.norm(x[25:], axis=1) <= 0.2 + 1e-12)
    moving = tc.Scene(gravity=(0.0, 0.0, 0.0))
    moving.add_emitter(tc.Sphere(radius=0.1), rate=600.0, velocity=(1.0, 2.0, 3.0), radius=0.004)
    moving.step(1)
    assert np.allclose(moving.velocities(), (1.0, 2.0, 3.0))


def test_a_stream_leaves_its_region_spaced_by_the_substeps_not_in_a_clump_per_frame():
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=1.0 / 600.0, substeps=10)
    # a thin slab at x = 0: one particle a substep, leaving along +x at 1 m/s
    scene.add_emitter(tc.Box(half_extents=(1e-4, 0.05, 0.05)), rate=600.0, radius=0.001, velocity=(1.0, 0.0, 0.0))
    scene.step(1)
    travelled = np.sort(scene.positions()[:, 0])
    # emitted at the start of substep k (k = 0..9), moved by the substeps from there to the frame's end
    assert np.allclose(travelled, np.arange(1, 11) / 600.0, atol=1.1e-4)


def test_an_emitter_without_room_emits_fewer_and_counts_the_rest():
    scene = still_scene()
    # a ball of 3 radii holds a few particles of radius 1, not 100 a frame
    emitter = scene.add_emitter(tc.Sphere(radius=0.03), rate=6000.0, radius=0.01, velocity=(0.0, 0.0, 0.0))
    with pytest.warns(RuntimeWarning, match="found no room"):
        scene.step(2)
    assert 1 <= emitter.emitted < 20 and emitter.emitted + emitter.skipped == 200
    assert scene.stats()["emission_skipped"] == emitter.skipped
    assert pairwise_gaps(scene.positions(), scene.radii()).min() >= 0.0
    # a hostile rate costs no more than a full region: 1e12 a second, counted, not tried
    flood = still_scene()
    torrent = flood.add_emitter(tc.Sphere(radius=0.03), rate=1e12, radius=0.01, velocity=(0.0, 0.0, 0.0))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        flood.step(1)
    assert [str(w.message) for w in caught if "found no room" in str(w.message)]
    assert not [w for w in caught if "holds its most" in str(w.message)]  # (the scene is far from full)
    assert torrent.emitted <= torrent.room and torrent.emitted + torrent.skipped == int(1e12 / 60)
    assert pairwise_gaps(flood.positions(), flood.radii()).min() >= 0.0


def test_an_emitter_stops_at_the_most_particles_a_scene_holds_and_counts_the_rest(monkeypatch):
    # the store's limit (Taichi's 32-bit offsets; hash_grid.MAX_LISTED with pairs) lowered to
    # 130: the emitter fills the scene up to it, warns once and counts what it could not add,
    # instead of failing the step
    monkeypatch.setattr("tai_coll.scene.particles.MAX_STORED", 130)
    scene = still_scene(dt=0.5 / FPS, substeps=2)
    scene.add_particles(positions=[[0.5, 0.5, 0.5]], radius=0.005)
    emitter = scene.add_emitter(tc.Box(half_extents=(0.2, 0.2, 0.2)), rate=100 * FPS, radius=0.005,
                                velocity=(0.0, 0.0, 0.0))
    scene.step(1)  # 100 owed, all added
    assert scene.num_particles == 101 and emitter.skipped == 0
    with pytest.warns(RuntimeWarning, match="holds its most, 130 particles") as caught:
        scene.step(2)  # 200 more owed: 29 fit
    assert len([w for w in caught if "holds its most" in str(w.message)]) == 1
    assert not [w for w in caught if "found no room" in str(w.message)]  # (the region had room)
    assert scene.num_particles == 130 and emitter.emitted == 129 and emitter.skipped == 171
    assert scene.stats()["emission_skipped"] == 171
    assert pairwise_gaps(scene.positions(), scene.radii()).min() >= 0.0


def test_new_particles_are_placed_clear_of_colliders_and_of_the_particles_there():
    scene = still_scene()
    ball = tc.Sphere(center=(0.0, 0.0, 0.0), radius=0.08)
    scene.add_collider(ball)
    scene.add_particles(positions=[[0.09, 0.0, 0.0], [0.0, 0.09, 0.0]], radius=0.005)
    scene.add_emitter(tc.Box(half_extents=(0.1, 0.1, 0.1)), rate=12000.0, radius=0.005, velocity=(0.0, 0.0, 0.0))
    scene.step(1)
    x = scene.positions()
    assert len(x) > 100
    assert np.all(ball.signed_distance(x[2:]) >= 0.005 - 1e-12)
    assert pairwise_gaps(x, scene.radii()).min() >= 0.0


def test_the_same_seed_emits_the_same_particles():
    runs = []
    for seed in (4, 4, 5):
        scene = still_scene()
        scene.add_emitter(tc.Box(half_extents=(0.05, 0.05, 0.05)), rate=1200.0, seed=seed, radius=0.004)
        scene.step(3)
        runs.append(scene.positions())
    assert np.array_equal(runs[0], runs[1]) and runs[0].shape == (60, 3)
    assert not np.array_equal(runs[0], runs[2])


@pytest.mark.parametrize("kwargs, error, name", [
    (dict(region=tc.Plane()), TypeError, "region"),
    (dict(rate=0.0), ValueError, "rate"),
    (dict(rate=float("inf")), ValueError, "rate"),
    (dict(radius=-1.0), ValueError, "radius"),
    (dict(mass=0.0), ValueError, "mass"),
    (dict(velocity=(1.0, 2.0)), ValueError, "velocity"),
    (dict(start=-1.0), ValueError, "start"),
    (dict(start=1.0, stop=0.5), ValueError, "stop"),
    (dict(max_particles=-1), ValueError, "max_particles"),
    (dict(max_particles=2.5), TypeError, "max_particles"),
    (dict(seed=-3), ValueError, "seed"),
])
def test_bad_emitter_arguments_are_refused_naming_them(kwargs, error, name):
    scene = still_scene()
    args = dict(region=tc.Sphere(radius=0.1), rate=100.0) | kwargs
    with pytest.raises(error, match=name):
        scene.add_emitter(args.pop("region"), **args)
    assert scene.emitters == []
    with pytest.raises(TypeError, match="region"):
        scene.add_sink(tc.Capsule())
    assert scene.sinks == []


@pytest.mark.filterwarnings("ignore:emitter 0:RuntimeWarning")  # (the region fills as the pile grows into it)
def test_emission_grows_the_store_without_compiling_a_kernel_per_frame(monkeypatch):
    from taichi.lang import kernel_impl

    scene = tc.Scene()
    scene.add_collider(tc.Plane(**FLOOR))
    scene.enable_particle_collisions()
    scene.add_emitter(tc.Box(center=(0.0, 0.03, 0.0), half_extents=(0.1, 0.02, 0.1)), rate=6000.0, radius=0.005)
    # 100 particles a frame: the store grows from 1,024 to 2,048 at frame 11 (compiling what a
    # growth needs, once: the copies of each array type) and to 4,096 at frame 21
    scene.step(12)
    compiled = []
    materialize = kernel_impl.Kernel.materialize

    def counting(self, key=None, args=None, arg_features=None):
        if key not in self.compiled_kernels:
            compiled.append(self.func.__name__)
        return materialize(self, key, args, arg_features)

    monkeypatch.setattr(kernel_impl.Kernel, "materialize", counting)
    capacity = scene._particles.capacity
    scene.step(14)
    assert scene._particles.capacity > capacity  # it grew ...
    assert compiled == []  # ... and no kernel compiled again


# ---------------------------------------------------------------- sinks and ids
def test_a_particle_falling_into_a_sink_disappears_and_its_id_never_returns():
    scene = tc.Scene()
    scene.add_sink(tc.Box(center=(0.0, -0.5, 0.0), half_extents=(0.2, 0.1, 0.2)))
    scene.add_particles(positions=[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], radius=0.01)
    scene.set_velocities([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 5.0, 0.0]])
    # falling from rest, the first centre enters the box's top (y = -0.4) at t = sqrt(0.8 / g) = 0.286 s
    scene.step(17)
    assert scene.num_particles == 3
    scene.step(1)
    assert scene.num_particles == 2 and np.array_equal(scene.ids(), [1, 2])
    assert scene.stats()["removed"] == 1
    x = scene.positions()
    assert x[0, 0] == 1.0 and x[1, 0] == 2.0  # readers in id order, the others unchanged
    scene.add_particles(positions=[[3.0, 0.0, 0.0]])
    assert np.array_equal(scene.ids(), [1, 2, 3])  # id 0 is never given again
    assert scene.positions()[2, 0] == 3.0


def test_sinks_with_an_emitter_and_pairs_keep_every_reader_in_id_order():
    scene = tc.Scene()
    scene.add_collider(tc.Plane(**FLOOR))
    scene.enable_particle_collisions()
    scene.add_emitter(tc.Box(center=(0.0, 0.15, 0.0), half_extents=(0.06, 0.03, 0.06)), rate=1800.0,
                      radius=0.006, velocity=(0.6, 0.0, 0.0))
    scene.add_sink(tc.Box(center=(0.2, 0.0, 0.0), half_extents=(0.03, 1.0, 1.0)))
    seen = set()
    for _ in range(25):
        scene.step(1)
        ids = scene.ids()
        assert np.all(np.diff(ids) > 0)
        removed = seen - set(ids.tolist())
        assert not removed & set(ids.tolist())
        seen |= set(ids.tolist())
        assert np.all(scene.positions()[:, 0] < 0.2 - 0.03 + 0.6 * scene.frame_time + 1e-9)  # none left in the sink
    stats = scene.stats()
    assert stats["removed"] > 20 and scene.num_particles == stats["emitted"] - stats["removed"]
    assert len(seen) == stats["emitted"]


# ---------------------------------------------------------------- frames through the scene
def test_save_frame_writes_the_same_particles_to_ply_npz_and_usd(tmp_path):
    plyfile = pytest.importorskip("plyfile")
    pxr = pytest.importorskip("pxr")
    import trimesh

    scene = tc.Scene()
    scene.add_collider(tc.Plane(**FLOOR))
    scene.add_particles(positions=[[0.0, 0.1, 0.0], [0.1, 0.2, 0.0], [0.2, 0.3, 0.0]], radius=[0.01, 0.02, 0.03])
    body = scene.add_body(tc.Box(center=(0.5, 0.2, 0.0), half_extents=(0.05, 0.05, 0.05)), density=300.0)
    scene.add_sink(tc.Box(center=(0.0, 0.1, 0.0), half_extents=(0.02, 0.02, 0.02)))  # takes the first
    scene.step(2)
    for ext in ("ply", "npz", "usda"):
        scene.save_frame(tmp_path / "sub" / f"f.{ext}")
    npz = np.load(tmp_path / "sub" / "f.npz")
    assert np.array_equal(npz["ids"], [1, 2]) and np.array_equal(npz["positions"], scene.positions())
    assert npz["frame"] == 2 and npz["time"] == scene.time
    assert np.array_equal(npz["body_positions"][0], body.position)
    ply = plyfile.PlyData.read(tmp_path / "sub" / "f.ply")["vertex"]
    assert np.array_equal(ply["id"], [1, 2]) and np.allclose(ply["radius"], [0.02, 0.03])
    cloud = trimesh.load(tmp_path / "sub" / "f.ply")
    assert np.allclose(cloud.vertices, scene.positions(), atol=1e-6)
    stage = pxr.Usd.Stage.Open(str(tmp_path / "sub" / "f.usda"))
    points = pxr.UsdGeom.Points(stage.GetPrimAtPath("/World/particles"))
    assert np.allclose(np.array(points.GetPointsAttr().Get(2)), scene.positions(), atol=1e-6)
    assert list(points.GetIdsAttr().Get(2)) == [1, 2]
    assert np.allclose(np.array(points.GetWidthsAttr().Get(2)), 2 * npz["radii"])
    raw = cloud.metadata["_ply_raw"]["vertex"]["data"]  # (trimesh keeps every vertex property)
    assert np.array_equal(raw["id"], npz["ids"]) and np.allclose(raw["radius"], npz["radii"])
    with pytest.raises(ValueError, match="extension|path"):
        scene.save_frame(tmp_path / "f.obj")
    assert not (tmp_path / "f.obj").exists()


# ---------------------------------------------------------------- save_state / load_state
def _workflow_scene():
    """Pairs with a body, an emitter and a sink: most of what a state holds."""
    rng = np.random.default_rng(3)
    scene = tc.Scene()
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(restitution=0.3, friction=0.4))
    scene.add_particles(positions=rng.uniform([-0.05, 0.01, -0.05], [0.05, 0.1, 0.05], (120, 3)), radius=0.008)
    scene.enable_particle_collisions()
    scene.add_body(tc.Box(center=(0.0, 0.2, 0.0), half_extents=(0.03, 0.015, 0.03)), density=400.0)
    scene.add_emitter(tc.Sphere(center=(0.0, 0.3, 0.0), radius=0.04), rate=900.0, radius=0.007,
                      velocity=(0.8, 0.0, 0.0), seed=7)
    scene.add_sink(tc.Box(center=(0.2, 0.0, 0.0), half_extents=(0.03, 0.5, 0.5)))
    return scene


def _dem_scene():
    """DEM pairs with tangential and rolling springs, spinning particles, Verlet lists, auto dt."""
    rng = np.random.default_rng(4)
    scene = tc.Scene(solver=tc.PenaltySolver(stiffness=2e4, spin=True), substeps="auto")
    scene.add_collider(tc.Plane(**FLOOR), material=tc.Material(friction=0.5))
    scene.add_particles(positions=rng.uniform([-0.04, 0.01, -0.04], [0.04, 0.08, 0.04], (150, 3)), radius=0.008,
                        mass=0.005)
    scene.enable_particle_collisions(tangential_springs=True, verlet_skin=0.002,
                                     material=tc.Material(friction=0.5, rolling_friction=0.1))
    return scene


def _moving_scene():
    """No pairs: a turning paddle, the impulse solver's kept clearances."""
    rng = np.random.default_rng(5)
    scene = tc.Scene()
    scene.add_collider(tc.Plane(**FLOOR))
    scene.add_collider(tc.Box(center=(0.0, 0.05, 0.0), half_extents=(0.1, 0.01, 0.02)), angular_velocity=(0, 4, 0))
    scene.add_particles(positions=rng.uniform([-0.1, 0.02, -0.1], [0.1, 0.2, 0.1], (200, 3)), radius=0.01)
    return scene


def _arrays(scene):
    out = [scene.positions(), scene.velocities(), scene.ids(), scene.angular_velocities(), scene.sleeping(),
           np.array([scene.time, scene.frame])]
    for body in scene.bodies:
        out += [body.position, body.rotation, body.velocity, body.angular_velocity]
    return out


@pytest.mark.filterwarnings("ignore:emitter 0:RuntimeWarning")  # (it skips a few: its counts are state too)
@pytest.mark.parametrize("build", [_workflow_scene, _dem_scene, _moving_scene])
def test_twenty_frames_equal_ten_then_a_checkpoint_then_ten_more(build, tmp_path):
    whole = build()
    whole.step(20)
    first = build()
    first.step(10)
    path = first.save_state(tmp_path / "state.npz")
    assert path.exists() and not [p for p in tmp_path.iterdir() if p.name != "state.npz"]  # no temporary left
    resumed = build()
    resumed.load_state(path)
    assert resumed.frame == 10 and resumed.time == first.time
    resumed.step(10)
    for a, b in zip(_arrays(whole), _arrays(resumed), strict=True):
        assert np.array_equal(a, b)
    assert whole.stats() == resumed.stats()
    first.step(10)  # saving did not disturb the run it came from
    for a, b in zip(_arrays(whole), _arrays(first), strict=True):
        assert np.array_equal(a, b)


def test_a_state_loaded_into_a_different_scene_is_refused_saying_what_differs(tmp_path):
    scene = _moving_scene()
    scene.step(1)
    path = scene.save_state(tmp_path / "s.npz")

    other = _moving_scene()
    other.add_collider(tc.Sphere(center=(1.0, 1.0, 1.0), radius=0.1))
    before = other.positions()
    with pytest.raises(ValueError, match="colliders: the state has 2, this scene 3"):
        other.load_state(path)
    assert np.array_equal(other.positions(), before) and other.frame == 0  # untouched

    solver = tc.Scene(solver=tc.PenaltySolver(stiffness=1e4))
    solver.add_collider(tc.Plane(**FLOOR))
    solver.add_collider(tc.Box(center=(0.0, 0.05, 0.0), half_extents=(0.1, 0.01, 0.02)), angular_velocity=(0, 4, 0))
    with pytest.raises(ValueError, match="solver"):
        solver.load_state(path)

    moved = tc.Scene()
    moved.add_collider(tc.Plane(**FLOOR))
    moved.add_collider(tc.Box(center=(0.0, 0.06, 0.0), half_extents=(0.1, 0.01, 0.02)), angular_velocity=(0, 4, 0))
    with pytest.raises(ValueError, match=r"colliders \[1\]"):
        moved.load_state(path)

    emitting = _moving_scene()
    emitting.add_emitter(tc.Sphere(radius=0.1), rate=10.0)
    with pytest.raises(ValueError, match="emitters"):
        emitting.load_state(path)


def test_load_state_refuses_missing_and_foreign_files_before_changing_anything(tmp_path):
    scene = _moving_scene()
    with pytest.raises(FileNotFoundError, match="path"):
        scene.load_state(tmp_path / "nowhere.npz")
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(ValueError, match="not a tai_coll state"):
        scene.load_state(tmp_path / "other.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="not a tai_coll state"):
        scene.load_state(tmp_path / "junk.npz")
    with pytest.raises(ValueError, match="path must end in .npz"):
        scene.save_state(tmp_path / "state.json")
    with pytest.raises(TypeError, match="path"):
        scene.save_state(3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["junk.npz", "other.npz"]


def test_a_failed_save_leaves_the_last_state_whole(tmp_path, monkeypatch):
    scene = _moving_scene()
    path = scene.save_state(tmp_path / "s.npz")
    good = path.read_bytes()
    scene.step(1)

    def broken(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", broken)
    with pytest.raises(OSError, match="disk full"):
        scene.save_state(path)
    assert path.read_bytes() == good and [p.name for p in tmp_path.iterdir()] == ["s.npz"]


# ---------------------------------------------------------------- the command line
SCRIPT = '''
import tai_coll as tc

FRAMES = 4


def scene():
    s = tc.Scene()
    s.add_collider(tc.Plane())
    s.enable_particle_collisions()
    s.add_emitter(tc.Box(center=(0, 0.1, 0), half_extents=(0.04, 0.02, 0.04)), rate=1200, radius=0.006)
    s.add_body(tc.Sphere(center=(0.15, 0.05, 0), radius=0.03), density=500)
    return s
'''


def tai_coll(*args, cwd):
    return subprocess.run([sys.executable, "-m", "tai_coll", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=900)


@pytest.mark.slow
def test_run_exports_checkpoints_and_resumes_to_the_same_frames(tmp_path):
    pytest.importorskip("pxr")
    script = tmp_path / "pour.py"
    script.write_text(SCRIPT)
    whole = tai_coll("run", script, "--no-render", "--export", "ply,npz,usd", "--checkpoint-every", "2",
                     "--arch", "cpu", "--threads", "2", "--out", tmp_path / "a", cwd=tmp_path)
    assert whole.returncode == 0, whole.stderr
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert names == (["particles.usd"] + [f"particles_{k:05d}.{e}" for k in range(5) for e in ("npz", "ply")]
                     + ["state_00002.npz", "state_00004.npz"])
    whole_run = {k: v for k, v in np.load(tmp_path / "a" / "particles_00004.npz").items()}
    from pxr import Usd, UsdGeom

    def usd_frames():
        stage = Usd.Stage.Open(str(tmp_path / "a" / "particles.usd"))
        points = UsdGeom.Points(stage.GetPrimAtPath("/World/particles"))
        assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, 4)
        return {t: (list(points.GetIdsAttr().Get(t)), np.array(points.GetPointsAttr().Get(t))) for t in range(5)}

    before = usd_frames()
    assert before[4][0] == whole_run["ids"].tolist() and np.allclose(before[4][1], whole_run["positions"], atol=1e-6)
    # resumed from frame 2 into the same folder: frames 3 and 4 again, the same to the bit
    part = tai_coll("run", script, "--no-render", "--export", "npz,usd", "--frames", "2", "--resume",
                    tmp_path / "a" / "state_00002.npz", "--arch", "cpu", "--threads", "2", "--out", tmp_path / "a",
                    cwd=tmp_path)
    assert part.returncode == 0, part.stderr
    again = np.load(tmp_path / "a" / "particles_00004.npz")
    for key, value in whole_run.items():
        assert np.array_equal(value, again[key]), key
    after = usd_frames()  # the layer kept frames 0 to 2 and took 3 and 4 from the resumed run
    for t in range(5):
        assert after[t][0] == before[t][0] and np.array_equal(after[t][1], before[t][1]), t


def test_run_refuses_an_unknown_export_format_before_anything_runs(tmp_path):
    script = tmp_path / "pour.py"
    script.write_text(SCRIPT)
    done = tai_coll("run", script, "--export", "ply,obj", "--out", tmp_path / "out", cwd=tmp_path)
    assert done.returncode == 2 and "unknown format 'obj'" in done.stderr
    bad = tai_coll("run", script, "--checkpoint-every", "0", "--out", tmp_path / "out", cwd=tmp_path)
    assert bad.returncode == 2 and "--checkpoint-every" in bad.stderr
    missing = tai_coll("run", script, "--resume", tmp_path / "none.npz", "--out", tmp_path / "out", cwd=tmp_path)
    assert missing.returncode == 2 and "--resume" in missing.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pour.py"]
