"""Sleeping particles (docs/physics.md 5.3.1): a pile comes to rest and stays still, with stored
velocities that describe its motion; anything that moves near it, a change of gravity or a
write of the state wakes it; a bounce or a drifting particle never sleeps."""

import numpy as np
import pytest

import tai_coll as tc
from tai_coll.solvers.pairs.sleeping import SLEEP_TIME
from tools import pile_settle

R = pile_settle.LATTICE_RADIUS
FRAME = 1 / 60


def lattice_pile(n_side):
    """The issue's pile, smaller: n_side^3 particles of radius R on a jittered lattice (2.2 R
    apart, no overlap) just above the floor of a box of planes; e = 0.3, mu = 0.5."""
    return pile_settle.lattice_pile(tc, n_side)


@pytest.fixture(scope="module")
def rested_pile():
    scene, half = lattice_pile(10)
    scene.step(120)  # 2 s after the drop
    return scene, half


def test_a_lattice_pile_is_still_two_seconds_after_the_drop(rested_pile):
    # The promise at a tenth of its size: stored speeds p99 <= 5 mm/s, max <= 20 mm/s,
    # mean overlap under 2 % of the radius, and the positions agree: over the next frame no
    # particle moves faster than its stored speed says (plus round-off).
    scene, _ = rested_pile
    speed = np.linalg.norm(scene.velocities(), axis=1)
    assert np.percentile(speed, 99) <= 5e-3
    assert speed.max() <= 20e-3
    assert scene.particle_overlap()["mean"] < 0.02
    before = scene.positions()
    scene.step()
    moved = np.linalg.norm(scene.positions() - before, axis=1) / FRAME
    assert np.percentile(moved, 99) <= 5e-3 and moved.max() <= 20e-3
    assert scene.sleeping().mean() > 0.9
    still = scene.sleeping()
    assert np.array_equal(scene.velocities()[still], np.zeros((still.sum(), 3)))


def test_a_fast_particle_wakes_the_particles_it_hits(rested_pile):
    # A particle fired at a sleeping pile wakes the ones it reaches (they move again), stops on
    # the pile instead of passing into it, and the pile falls asleep again afterwards.
    scene, half = rested_pile
    top = scene.positions()[:, 1].max()
    n = scene.num_particles
    assert scene.sleeping().all()
    scene.add_particles(positions=[[0.0, top + 4 * R, 0.0]], velocities=[[0.0, -2.0, 0.0]], radius=R)
    scene.step(2)
    x = scene.positions()
    woken = np.flatnonzero(~scene.sleeping()[:n])
    # the hit goes on through the particles it wakes within the substep, but stays local
    assert 1 <= len(woken) < 0.05 * n
    assert np.all(np.linalg.norm(x[woken] - x[n], axis=1) < 10 * R)
    assert top - R < x[n, 1] < top + 2.5 * R
    assert scene.particle_overlap()["max"] < 0.5
    scene.step(60)
    assert scene.sleeping().all()


def test_a_change_of_gravity_wakes_everything():
    scene, half = lattice_pile(6)
    scene.step(90)
    assert scene.sleeping().any()
    scene.gravity = (9.81, -9.81, 0.0)  # the box tips over
    assert not scene.sleeping().any()
    before = scene.positions()[:, 0].mean()
    scene.step(20)
    assert scene.positions()[:, 0].mean() > before + 0.1 * R


def test_writing_velocities_wakes_the_particles():
    scene, _ = lattice_pile(6)
    scene.step(90)
    assert scene.sleeping().any()
    v = np.zeros((scene.num_particles, 3))
    v[:, 1] = 0.5
    scene.set_velocities(v)
    assert not scene.sleeping().any()
    y = scene.positions()[:, 1].mean()
    scene.step()
    assert scene.positions()[:, 1].mean() > y


def test_particles_do_not_sleep_beside_a_kinematic_collider():
    # a moving collider can take a support away without touching the particle: no sleeping
    scene = tc.Scene()
    scene.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)))
    scene.add_collider(tc.Sphere(center=(1.0, 0.5, 0.0), radius=0.1), velocity=(0.0, 0.0, 0.01))
    scene.enable_particle_collisions(sleep_time=0.3)
    scene.add_particles(positions=[[0.0, R, 0.0], [2 * R, R, 0.0], [R, R + 1.8 * R, 0.0]], radius=R)
    scene.step(60)
    assert not scene.sleeping().any()


def test_a_slow_particle_in_free_flight_never_sleeps():
    # held by nothing (its velocity is what gravity gives it), however slow
    scene = tc.Scene(gravity=(0, 0, 0))
    scene.enable_particle_collisions(sleep_time=0.3)
    scene.add_particles(positions=[[0.0, 0.0, 0.0]], velocities=[[1e-4, 0.0, 0.0]], radius=R)
    scene.step(90)
    assert not scene.sleeping().any()
    assert scene.positions()[0, 0] == pytest.approx(1e-4 * 1.5, rel=1e-3)


def test_without_gravity_nothing_sleeps_and_slow_collisions_keep_momentum():
    # A lattice of particles of random masses and slow random velocities, no gravity: nothing
    # presses them together, so nothing sleeps (before, those slowed by inelastic contacts
    # fell asleep and, immovable to the passes, took momentum out of later exchanges: 3.6e-4
    # of M * 0.3 m/s over 30 frames); momentum stays to round-off
    rng = np.random.default_rng(4)
    lattice = np.stack(np.meshgrid(*[np.arange(8)] * 3, indexing="ij"), -1).reshape(-1, 3) * 2.1 * R
    masses = rng.uniform(0.5, 2.0, len(lattice))
    v0 = rng.normal(0.0, 0.1, lattice.shape)
    scene = tc.Scene(gravity=(0, 0, 0), dt=1 / 600, substeps=10)
    scene.enable_particle_collisions(sleep_time=0.3, material=tc.Material(restitution=0.2))
    scene.add_particles(positions=lattice, velocities=v0, mass=masses, radius=R)
    momentum = masses @ v0
    for _ in range(40):
        scene.step()
        assert not scene.sleeping().any()
        assert np.allclose(masses @ scene.velocities(), momentum, rtol=0.0, atol=1e-12)


def test_a_bounce_keeps_its_restitution_with_sleeping_on():
    # e^2 h: the apex after the first bounce of a particle dropped from h onto a plane
    e, h = 0.6, 0.2
    scene = tc.Scene(dt=1e-4, substeps=10)
    scene.add_collider(tc.Plane(point=(0, 0, 0), normal=(0, 1, 0)), material=tc.Material(restitution=e))
    scene.enable_particle_collisions(sleep_time=0.3)
    scene.add_particles(positions=[[0.0, h + R, 0.0]], radius=R)
    apex, bounced = 0.0, False
    for _ in range(700):
        scene.step()
        v, y = scene.velocities()[0, 1], scene.positions()[0, 1] - R
        bounced = bounced or v > 0
        if bounced:
            apex = max(apex, y)
    assert apex == pytest.approx(e * e * h, rel=0.02)


@pytest.mark.parametrize("kwargs, error, match", [
    ({"method": "jacobi", "sleep_time": 0.5}, ValueError, "gauss-seidel"),
    ({"sleep_time": 0.0}, ValueError, "sleep_time"),
    ({"sleep_time": -1.0}, ValueError, "sleep_time"),
    ({"sleep_time": "long"}, ValueError, "sleep_time"),
    ({"sleep_time": [0.3]}, TypeError, "sleep_time"),
    ({"sleep_drift": -0.1}, ValueError, "sleep_drift"),
    ({"wake_speed": -1.0}, ValueError, "wake_speed"),
])
def test_sleep_settings_are_checked(kwargs, error, match):
    scene = tc.Scene()
    with pytest.raises(error, match=match):
        scene.enable_particle_collisions(**kwargs)


def test_sleeping_is_on_by_default_for_gauss_seidel_and_jacobi_has_none():
    scene = tc.Scene()
    assert scene.enable_particle_collisions().settings.sleep_time == SLEEP_TIME
    assert scene.enable_particle_collisions(sleep_time=None).settings.sleep_time is None
    assert scene.enable_particle_collisions(sleep_time=0.5).settings.sleep_time == 0.5
    assert scene.enable_particle_collisions(method="jacobi").settings.sleep_time is None
    with pytest.raises(ValueError, match="sleep_time"):
        scene.enable_particle_collisions(sleep_time="soon")


def sleeping_row(count):
    """`count` touching particles in a row along x on a frictionless floor, e = 1 between
    them, stepped until asleep."""
    scene = tc.Scene(dt=1 / 1000, substeps=5)
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=0.0, friction=0.0))
    scene.enable_particle_collisions(material=tc.Material(restitution=1.0, friction=0.0))
    scene.add_particles(positions=np.stack([2 * R * np.arange(count), np.full(count, R), np.zeros(count)], 1),
                        radius=R)
    scene.step(400)
    assert scene.sleeping().all()
    return scene


@pytest.mark.parametrize("start", [3.0, 2.15])
def test_a_hit_on_a_sleeping_row_goes_on_into_it(start):
    # A particle hits the end of a sleeping row at 1 m/s (from start radii away: woken early,
    # the end particle is at rest again when the hit comes): the row wakes and takes the
    # hitter's momentum on, nobody ends faster than the hit, no momentum appears. (Before a
    # particle at rest handed on a hit, the end particle stopped it dead: nothing moved on.
    # Part of it is still lost where the push slows below HIT_FACTOR * wake_speed: see
    # sleeping.py.)
    scene = sleeping_row(8)
    scene.add_particles(positions=[[-start * R, R, 0.0]], velocities=[[1.0, 0.0, 0.0]], radius=R)
    scene.step(3)
    v = scene.velocities()
    assert not scene.sleeping().any()
    assert v[8, 0] < 0.1  # the hitter gave its momentum away ...
    assert v[:8, 0].sum() > 0.4  # ... to the row
    assert v[:, 0].sum() <= 1.0 + 1e-4 and np.abs(v).max() <= 1.0 + 1e-4


def test_a_sleeping_row_falls_asleep_again_after_a_slow_push():
    scene = sleeping_row(4)
    scene.add_particles(positions=[[-2.5 * R, R, 0.0]], velocities=[[0.2, 0.0, 0.0]], radius=R)
    scene.step(10)
    assert not scene.sleeping().all()
    scene.step(600)
    assert scene.sleeping().all() and np.abs(scene.velocities()).max() == 0.0


def test_a_collider_added_where_particles_sleep_wakes_them():
    # A wall added through a sleeping particle pushes it out: it wakes, instead of sleeping on
    # inside the wall (a sleeping particle keeps its place, and the colliders' passes leave it
    # alone: they hold still while particles sleep).
    scene = sleeping_row(1)
    x = scene.positions()[0]
    wall = x[0] - 0.5 * R
    scene.add_collider(tc.Plane(point=(wall, 0.0, 0.0), normal=(-1.0, 0.0, 0.0)))
    scene.step(1)
    assert not scene.sleeping().any()
    scene.step(20)
    assert scene.positions()[0, 0] <= wall - 0.99 * R
    assert abs(scene.positions()[0, 1] - R) < 1e-3 * R  # still on the floor


@pytest.mark.parametrize("wake", ["gravity", "velocities", "collider"])
def test_substeps_where_every_particle_sleeps_are_skipped_and_change_nothing(wake, monkeypatch):
    # Once every particle sleeps, a substep would leave the state as it was: it is skipped (no
    # lists built), and the state stays the same to the bit, as the substeps that are not
    # skipped leave it. What wakes particles from outside ends the skipping.
    from tai_coll.solvers.pairs import collisions

    skipped = sleeping_row(3)
    full = sleeping_row(3)
    pairs = skipped.particle_collisions
    builds, full_builds = pairs.list_builds, full.particle_collisions.list_builds
    x, v = skipped.positions(), skipped.velocities()
    skipped.step(10)
    with monkeypatch.context() as patch:  # the same substeps, none skipped
        patch.setattr(collisions, "all_asleep", lambda awake, then, now: False)
        full.step(10)
    assert pairs.list_builds == builds and full.particle_collisions.list_builds == full_builds + 50
    for scene in (skipped, full):
        assert np.array_equal(scene.positions(), x) and np.array_equal(scene.velocities(), v)
        assert scene.sleeping().all()
    for scene in (skipped, full):
        if wake == "gravity":
            scene.gravity = (2.0, -9.81, 0.0)  # the row slides along x on its frictionless floor
        elif wake == "velocities":
            scene.set_velocities(np.tile([0.2, 0.0, 0.0], (3, 1)))
        else:  # a wall just touching the last particle, which holds it and wakes them all
            scene.add_collider(tc.Plane(point=(x[2, 0] + R, 0.0, 0.0), normal=(-1.0, 0.0, 0.0)))
        scene.step(5)
    assert pairs.list_builds == builds + 25
    assert np.array_equal(skipped.positions(), full.positions())
    assert np.array_equal(skipped.velocities(), full.velocities())
    if wake != "collider":
        assert skipped.positions()[:, 0].mean() > x[:, 0].mean() + 0.1 * R


def test_a_sleeping_row_resumed_from_a_state_skips_as_the_saved_run_would(tmp_path):
    # save_state keeps what the skip watches: the resumed run skips the substeps the saved one
    # skips, and ends with the same state to the bit once woken.
    scene = sleeping_row(3)
    path = scene.save_state(tmp_path / "asleep.npz")
    resumed = tc.Scene(dt=1 / 1000, substeps=5)
    resumed.add_collider(tc.Plane(), material=tc.Material(restitution=0.0, friction=0.0))
    resumed.enable_particle_collisions(material=tc.Material(restitution=1.0, friction=0.0))
    resumed.load_state(path)
    for run in (scene, resumed):
        builds = run.particle_collisions.list_builds
        run.step(4)
        assert run.particle_collisions.list_builds == builds
        run.gravity = (2.0, -9.81, 0.0)
        run.step(6)
    assert np.array_equal(resumed.positions(), scene.positions())
    assert np.array_equal(resumed.velocities(), scene.velocities())


def no_elastic_wakes(monkeypatch):
    """Make the elastic passes wake nobody (their wake speed out of reach), so that the wakes
    come in the later passes of a substep."""
    from tai_coll.solvers.pairs import gauss_seidel

    velocity_pass = gauss_seidel.velocity_pass

    def patched(elastic, *args, wake_speed=None, **kwargs):
        if elastic and wake_speed is not None:
            wake_speed = 1e9
        return velocity_pass(elastic, *args, wake_speed=wake_speed, **kwargs)

    monkeypatch.setattr(gauss_seidel, "velocity_pass", patched)


def pile_with_balls_landing():
    """A lattice pile of 512 falling asleep, and twelve balls landing in it 1.0 to 1.7 s after
    the drop, one after another, each waking part of it."""
    scene, half = lattice_pile(8)
    rng = np.random.default_rng(1)
    xz = rng.uniform(-0.7 * half, 0.7 * half, (12, 2))
    heights = 0.5 * 9.81 * np.linspace(1.0, 1.7, 12) ** 2
    scene.add_particles(positions=np.column_stack([xz[:, 0], heights, xz[:, 1]]), radius=0.8 * R)
    return scene


@pytest.mark.parametrize("elastic_wakes", [True, False])
def test_quiet_particles_passed_over_change_nothing(elastic_wakes, monkeypatch):
    # The later pair passes of a substep pass over a particle that sleeps with only sleeping
    # partners, while nothing has woken (gauss_seidel._pass, QUIET): the same state to the bit,
    # every frame, as a run whose passes walk every particle, through the pile falling asleep,
    # balls dropped into it one after another waking parts of it, and its sleeping again. With
    # elastic_wakes False the elastic passes wake nobody (both runs alike), so that wakes come in
    # the contact passes, after quiet particles were marked: a wake must end the passing over
    # within the walk it happens in.
    from tai_coll.solvers.pairs import gauss_seidel

    if not elastic_wakes:
        no_elastic_wakes(monkeypatch)

    def run(skip):
        monkeypatch.setattr(gauss_seidel, "QUIET_SKIP", skip)
        scene = pile_with_balls_landing()
        frames, flags = [], []
        for _ in range(110):
            scene.step()
            frames.append((scene.positions(), scene.velocities()))
            work = gauss_seidel.pass_work(scene.num_particles)  # (the last substep's marks and flags)
            quiet = work["quiet"].to_numpy()[:scene.num_particles]
            flags.append((int(quiet.sum()), tuple(work["woke"].to_numpy())))
        return frames, flags

    passed, flags = run(True)
    walked, _ = run(False)
    for (x, v), (x_all, v_all) in zip(passed, walked):
        assert np.array_equal(x, x_all) and np.array_equal(v, v_all)
    assert any(quiet > 100 and woke == (0, 1) for quiet, woke in flags)  # passed over quiet particles
    assert any(woke[0] == 1 for _, woke in flags)  # ... and substeps whose passes recorded a wake
    assert (np.min([x[-12:, 1] for x, _ in passed], axis=0) < 0.25).all()  # every ball came down onto the pile


@pytest.mark.parametrize("elastic_wakes", [True, False])
def test_lists_of_the_awake_change_nothing(elastic_wakes, monkeypatch):
    # After calm substeps, a sleeping particle with nothing awake near lists nothing, and a
    # substep whose passes wake a particle is undone and run again with whole lists
    # (solvers/pairs/awake_lists.py): the same state to the bit, every frame, as whole lists
    # throughout, through the pile falling asleep and balls landing in it one after another.
    # With elastic_wakes False the elastic passes wake nobody (both runs alike): the wakes come
    # in the later passes, after the colliders' passes moved the candidates.
    from tai_coll.solvers.pairs import awake_lists

    if not elastic_wakes:
        no_elastic_wakes(monkeypatch)
    counts = {"awake lists": 0, "again": 0}
    wanted, again = awake_lists.Calm.wanted, awake_lists.again

    def counted_wanted(calm, may):
        used = wanted(calm, may)
        counts["awake lists"] += used
        return used

    def counted_again(*args):
        counts["again"] += 1
        return again(*args)

    monkeypatch.setattr(awake_lists.Calm, "wanted", counted_wanted)
    monkeypatch.setattr(awake_lists, "again", counted_again)

    def run(on):
        monkeypatch.setattr(awake_lists, "AWAKE_LISTS", on)
        scene = pile_with_balls_landing()
        frames = []
        for _ in range(110):
            scene.step()
            frames.append((scene.positions(), scene.velocities()))
        return frames, scene.particle_collisions.neighbour_overflow

    (slim, dropped), seen = run(True), dict(counts)
    (whole, dropped_whole) = run(False)
    assert counts == seen  # (the second run never used them)
    for (x, v), (x_all, v_all) in zip(slim, whole):
        assert np.array_equal(x, x_all) and np.array_equal(v, v_all)
    assert dropped == dropped_whole
    assert seen["awake lists"] > 100 and seen["again"] >= 3, seen  # both ways taken
    assert (np.min([x[-12:, 1] for x, _ in slim], axis=0) < 0.25).all()  # every ball came down onto the pile


def test_undoing_a_substep_of_lists_of_the_awake_restores_what_its_passes_changed():
    # awake_lists.undo: the particles the passes woke (rest time sleeping.WOKEN) asleep again,
    # every position back at x(t) (where the colliders' last resort may have pushed one); the
    # other rest times as they were
    import taichi as ti

    from tai_coll.solvers.pairs import awake_lists, sleeping

    scene = tc.Scene(dt=1 / 1000)
    x = np.column_stack([np.arange(5) * 0.1, np.full(5, 0.2), np.zeros(5)])
    scene.add_particles(positions=x, radius=R)
    store = scene._particles
    x_start = ti.Vector.ndarray(3, float, shape=store.capacity)
    x_start.from_numpy(np.resize(x, (store.capacity, 3)).astype(store.x.to_numpy().dtype))
    scene.set_positions(x + 0.01)  # (as a push would have)
    kind = store.rest.to_numpy().dtype
    rest = np.array([sleeping.WOKEN, sleeping.ASLEEP, 0.0, 0.25, sleeping.WOKEN], dtype=kind)
    store.rest.from_numpy(np.resize(rest, store.capacity))
    awake_lists.undo(store.args, x_start)
    assert np.array_equal(store.rest.to_numpy()[:5],
                          np.array([sleeping.ASLEEP, sleeping.ASLEEP, 0.0, 0.25, sleeping.ASLEEP], dtype=kind))
    assert np.array_equal(scene.positions(), x.astype(kind))
