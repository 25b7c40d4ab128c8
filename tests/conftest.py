"""Taichi starts once per test session: f64, fixed seed, on the CPU backend with 2 threads.

TAI_COLL_TEST_ARCH=cuda (or another arch `tc.init` takes) runs the same suite on that
backend instead, for checking the kernels on a GPU; CI and the README's test command use
the CPU.

Below the session set-up: constants and scene builders that several test files share,
imported as `from conftest import ...` (tests/ is on sys.path in pytest's default import
mode, as for triangle_oracle.py). Helpers that one file uses stay in that file. tai_coll's
internal modules are imported inside the helpers that need them, so that a module moving
breaks those tests only, not the session.
"""

import os

import numpy as np
import pytest

import tai_coll as tc

TEST_ARCH = os.environ.get("TAI_COLL_TEST_ARCH", "cpu")


def pytest_configure(config):
    # pytest-xdist (the README's command): hand out the test files in the order collected
    # (pytest_collection_modifyitems below), not by their count of tests, which put the file
    # of the heaviest cases (test_scenes.py, several minutes alone) last: the other process
    # then sat idle for minutes at the end
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False
    if TEST_ARCH == "cpu":
        tc.init(arch="cpu", precision="f64", threads=2, seed=0)
    else:
        info = tc.init(arch=TEST_ARCH, precision="f64", seed=0)
        if info.arch != TEST_ARCH:
            raise pytest.UsageError(f"TAI_COLL_TEST_ARCH={TEST_ARCH!r}, but Taichi started on {info.arch!r}")


def pytest_collection_modifyitems(config, items):
    """Files with slow-marked cases first, the most such cases first (the order within a
    file kept): spread over two processes a file at a time, the longest files start early."""
    slow = {}
    for item in items:
        slow[item.path] = slow.get(item.path, 0) + (item.get_closest_marker("slow") is not None)
    first_seen = {path: k for k, path in enumerate(slow)}
    items.sort(key=lambda item: (-slow[item.path], first_seen[item.path]))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


# ---------------------------------------------------------------- gravity, floor, incline
G = 9.81  # m/s^2
FLOOR = dict(point=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0))  # tc.Plane(**FLOOR): the floor y = 0

# The incline: a plane through the origin at THETA = 30 degrees, rising toward +x.
THETA = np.radians(30.0)
INCLINE_N = np.array([-np.sin(THETA), np.cos(THETA), 0.0])
DOWNHILL = -np.array([np.cos(THETA), np.sin(THETA), 0.0])


def on_incline(scene, material, radius, *, depth=0.0, mass=1.0):
    """Add the incline (normal INCLINE_N) with `material` and one particle of `radius` and
    `mass` on it, `depth` into it (0: touching; a penalty contact's resting depth holds the
    normal force at once). Returns the particle's start position."""
    scene.add_collider(tc.Plane(point=(0.0, 0.0, 0.0), normal=INCLINE_N), material=material)
    start = (radius - depth) * INCLINE_N
    scene.add_particles(positions=[start], radius=radius, mass=mass)
    return start


def tilted_gravity(theta):
    """Gravity tilted by theta (rad) toward +x: what is level in the scene is an incline of theta."""
    return (G * np.sin(theta), -G * np.cos(theta), 0.0)


# ---------------------------------------------------------------- particle-particle scenes
def add_box_of_planes(scene, half, material):
    """A floor and four walls at x, z = +-half (an open box of planes), all of `material`."""
    walls = [((0, 0, 0), (0, 1, 0)), ((-half, 0, 0), (1, 0, 0)), ((half, 0, 0), (-1, 0, 0)),
             ((0, 0, -half), (0, 0, 1)), ((0, 0, half), (0, 0, -1))]
    for point, normal in walls:
        scene.add_collider(tc.Plane(point=point, normal=normal), material=material)


def pile_scene(*, box=None, **options):
    """Impulse pairs under gravity (dt 1 ms, 5 substeps) on a floor, or in a box of planes
    of half width `box`; restitution 0.2 and friction 0.4 everywhere. options: those of
    enable_particle_collisions. Returns (scene, pair settings)."""
    scene = tc.Scene(dt=1 / 1000, substeps=5)
    if box is None:
        scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.2, friction=0.4))
    else:
        add_box_of_planes(scene, box, tc.Material(restitution=0.2, friction=0.4))
    settings = scene.enable_particle_collisions(material=tc.Material(restitution=0.2, friction=0.4), **options)
    return scene, settings


def dem_scene(*, material=None, springs=False, **solver):
    """DEM pairs without gravity (dt 2e-5 s, 10 substeps, tc.PenaltySolver(**solver));
    material: the pairs' (default: no friction); springs: tangential springs."""
    scene = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=2e-5, substeps=10, solver=tc.PenaltySolver(**solver))
    scene.enable_particle_collisions(material=tc.Material(friction=0.0) if material is None else material,
                                     tangential_springs=springs)
    return scene


def assert_stack_rests_in_contact(scene, r, count):
    """A column of `count` particles of radius r on a floor: still, every neighbour touching
    (no gap wider than round-off), overlaps below 5 % of r, the lowest one on the floor."""
    assert np.abs(scene.velocities()).max() < 1e-3
    y = np.sort(scene.positions()[:, 1])
    xz = scene.positions()[:, [0, 2]]
    assert len(y) == count and np.abs(xz - xz[0]).max() < 1e-6  # still a column
    assert np.all(np.diff(y) - 2 * r < 1e-5 * r)
    assert scene.particle_overlap()["max"] < 0.05
    assert y[0] == pytest.approx(r, abs=1e-3 * r)


def crowded_particle(count, seed, offset=(0.0, 0.0, 0.0)):
    """A big particle (r 0.1, 5 kg) overlapped by `count` small ones (r 0.02, 0.5 to 2 kg) in
    random directions, some of which overlap each other: positions, radii, masses."""
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    small = directions * rng.uniform(0.105, 0.118, (count, 1))  # overlapping the big one (r 0.1 + 0.02)
    x = np.vstack([[0.0, 0.0, 0.0], small]) + offset
    radius = np.concatenate([[0.1], np.full(count, 0.02)])
    mass = np.concatenate([[5.0], rng.uniform(0.5, 2.0, count)])
    return x, radius, mass


def spring_law_velocities(x, radius, mass, k, dt):
    """Brute force: the velocities after one substep from rest with undamped DEM springs and no
    gravity, dt/m times the sum of k overlap n over every touching pair; and which pairs touch."""
    d = x[:, None, :] - x[None, :, :]
    dist = np.linalg.norm(d, axis=2)
    overlap = radius[:, None] + radius[None, :] - dist
    np.fill_diagonal(overlap, 0.0)
    touching = overlap > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        force = np.where(touching[:, :, None], k * overlap[:, :, None] * d / dist[:, :, None], 0.0).sum(axis=1)
    return dt * force / mass[:, None], touching


# ---------------------------------------------------------------- the hash grid on host arrays
def on_device(a):
    """A Taichi ndarray holding the host array a: integers as i32, floats in the session's
    precision (n x 3 as vectors)."""
    import taichi as ti
    from tai_coll import runtime

    a = np.asarray(a)
    if np.issubdtype(a.dtype, np.integer):
        out = ti.ndarray(ti.i32, shape=len(a))
        out.from_numpy(a.astype(np.int32))
    else:
        out = ti.Vector.ndarray(3, float, shape=len(a)) if a.ndim == 2 else ti.ndarray(float, shape=len(a))
        out.from_numpy(a.astype(runtime.float_dtype()))
    return out


def grid_of(x, radius, margin, forward=False):
    """A HashGrid built on host arrays (positions x, radii), every particle simulated."""
    from tai_coll.neighbors import HashGrid

    n = len(x)
    grid = HashGrid()
    grid.build(on_device(x), on_device(radius), on_device(np.zeros(n, int)), n, 2 * radius.max() + margin, margin,
               forward=forward)
    return grid


def bar_frames(n, width=64, height=48):
    """n (height, width, 3) uint8 frames with a bar that grows from frame to frame (its width
    survives video compression)."""
    out = []
    for k in range(n):
        f = np.zeros((height, width, 3), dtype=np.uint8)
        f[:, : (k + 1) * width // n] = (200, 80, 40)
        out.append(f)
    return out


def bad_codec_writer():
    """A VideoWriter whose ffmpeg command names an encoder that does not exist (ffmpeg fails)."""
    from tai_coll.render import VideoWriter

    class BadCodec(VideoWriter):
        def command(self, width, height, output):
            cmd = super().command(width, height, output)
            cmd[cmd.index("libx264")] = "no_such_encoder"
            return cmd

    return BadCodec
