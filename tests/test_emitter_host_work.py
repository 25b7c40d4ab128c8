"""The host's share of an emitter's substep and of a collider's host query, made cheaper
without changing a result: candidate points spaced apart with one table of distances, the
particle pack's count set in place on the CPU, and each collider's query pack made once.
Each test compares the short path with the long one it replaced."""

import gc

import numpy as np
import pytest

import tai_coll as tc


@pytest.mark.parametrize("seed", range(6))
def test_spacing_candidates_with_one_distance_table_takes_the_points_the_loop_takes(seed, monkeypatch):
    from tai_coll.scene import emitters

    rng = np.random.default_rng(seed)
    points = rng.uniform(-0.03, 0.03, (int(rng.integers(2, 900)), 3))
    points[1] = points[0]  # a duplicate, and a pair exactly at the gap: the loop's < decides both
    points[3] = points[2] + (0.01, 0.0, 0.0)
    gap2, most = 0.01 ** 2, int(rng.integers(1, 60))
    table = emitters._spaced(points, gap2, most)
    monkeypatch.setattr(emitters, "PAIRWISE", 0)  # every count takes the point-by-point loop
    loop = emitters._spaced(points, gap2, most)
    assert table.shape == loop.shape and np.array_equal(table, loop)
    assert 1 <= len(table) <= most
    d2 = np.sum((table[:, None] - table[None]) ** 2, axis=2) + np.eye(len(table))
    assert d2.min() >= gap2  # (the law itself: no two taken points nearer than the gap)


def _emitting_scene():
    scene = tc.Scene(dt=1.0 / 600.0, substeps=5)
    scene.add_collider(tc.Plane())
    side = np.arange(6) * 0.0202
    x = np.stack(np.meshgrid(side, side, side, indexing="ij"), -1).reshape(-1, 3) + (0.0, 0.005, 0.0)
    scene.add_particles(positions=x, radius=0.005)
    scene.enable_particle_collisions()
    scene.add_emitter(tc.Box(center=(0.05, 0.25, 0.05), half_extents=(0.05, 0.02, 0.05)), rate=3000.0, radius=0.005,
                      velocity=(0.0, -1.0, 0.0))
    return scene


def test_an_emitting_scene_sets_its_pack_count_in_place_and_ends_as_with_new_packs(monkeypatch):
    from tai_coll.scene.particles import ParticleStore

    kept = _emitting_scene()
    kept.step(1)
    pack = kept._particles.args
    kept.step(3)
    assert kept._particles.args is pack  # (the CPU: the same pack, its count set in place)
    assert pack["count"] == kept.num_particles > 216

    def rebuilt(store):
        store._args = None  # the long path: a new pack whenever the count changes
    monkeypatch.setattr(ParticleStore, "_count_changed", rebuilt)
    fresh = _emitting_scene()
    fresh.step(4)
    assert fresh.num_particles == kept.num_particles
    assert np.array_equal(fresh.positions(), kept.positions())
    assert np.array_equal(fresh.velocities(), kept.velocities())


def test_a_collider_queried_keeps_one_pack_which_leaves_with_it_and_no_other_collider_reads_it():
    from tai_coll.geometry import queries

    points = np.random.default_rng(3).uniform(-1.0, 1.0, (64, 3))
    box = tc.Box(center=(0.1, 0.0, 0.0), half_extents=(0.3, 0.2, 0.4))
    first = box.signed_distance(points)
    assert len(queries._PACKS) >= 1 and id(box) in queries._PACKS
    np.testing.assert_array_equal(box.signed_distance(points), first)  # (from the kept pack)
    key = id(box)
    del box
    gc.collect()
    assert key not in queries._PACKS
    # colliders made later (one may reuse the freed id) answer for their own shapes
    for radius in (0.25, 0.5, 0.75):
        sphere = tc.Sphere(radius=radius)
        np.testing.assert_allclose(sphere.signed_distance(points), np.linalg.norm(points, axis=1) - radius,
                                   atol=1e-12)
        del sphere
