"""tc.TriangleMesh: exact triangle queries against NumPy oracles (tests/triangle_oracle.py),
and the physics they serve: a zero-thickness sheet stops fast particles from either side,
a moving sheet carries what it touches, particles stay in an open bowl.

The session runs in f64 (tests/conftest.py).
"""

import numpy as np
import pytest
import trimesh

import tai_coll as tc
from tai_coll.geometry.mesh_grid import bin_triangles
from triangle_oracle import nearest, segment_first_hit, swept_contact, winding_number

PHI_TOL = 1e-9      # distances (f64)
NORMAL_TOL = 1e-7   # normals away from the medial axis
T_TOL = 1e-6        # crossing fractions (the oracle bisects to ~1e-18; its sampling is the limit)


def sheet(n=8, size=1.0, y=0.0):
    """A flat square of 2 n^2 triangles in the plane y, spanning [-size, size] in x and z,
    with a ripple-free but irregular diagonal pattern."""
    xs = np.linspace(-size, size, n + 1)
    X, Z = np.meshgrid(xs, xs, indexing="ij")
    V = np.column_stack([X.ravel(), np.full(X.size, y), Z.ravel()])
    faces = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = i * (n + 1) + j, (i + 1) * (n + 1) + j, (i + 1) * (n + 1) + j + 1, i * (n + 1) + j + 1
            faces += [[a, b, c], [a, c, d]] if (i + j) % 2 else [[a, b, d], [b, c, d]]
    return V, np.array(faces)


def bowl(radius=0.5, subdivisions=3):
    """The lower half of an icosphere: an open bowl."""
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    keep = sphere.vertices[sphere.faces].mean(axis=1)[:, 1] < 0.0
    return trimesh.Trimesh(sphere.vertices, sphere.faces[keep], process=True)


def torus():
    return trimesh.creation.torus(major_radius=0.5, minor_radius=0.2, major_sections=24, minor_sections=12)


def triangles_of(vertices, faces):
    return np.asarray(vertices, float)[np.asarray(faces)]


# ---------------------------------------------------------------------------- grid

def test_grid_bins_every_triangle_in_every_cell_its_box_overlaps(rng):
    """The counting sort in Taichi against a NumPy binning of the same boxes."""
    mesh = tc.TriangleMesh(torus(), cell_size=0.11)
    verts = mesh.vertices
    tris = mesh.faces
    starts, ids = bin_triangles(verts, tris.astype(np.int32), mesh.grid_origin, mesh.cell_size, mesh.grid_dims)
    nx, ny, nz = mesh.grid_dims
    expected = [[] for _ in range(nx * ny * nz)]
    for t, f in enumerate(tris):
        lo = np.clip(np.floor((verts[f].min(axis=0) - mesh.grid_origin) / mesh.cell_size), 0, mesh.grid_dims - 1)
        hi = np.clip(np.floor((verts[f].max(axis=0) - mesh.grid_origin) / mesh.cell_size), 0, mesh.grid_dims - 1)
        for i in range(int(lo[0]), int(hi[0]) + 1):
            for j in range(int(lo[1]), int(hi[1]) + 1):
                for k in range(int(lo[2]), int(hi[2]) + 1):
                    expected[(i * ny + j) * nz + k].append(t)
    assert starts[0] == 0 and starts[-1] == len(ids)
    for cell, want in enumerate(expected):
        assert ids[starts[cell]:starts[cell + 1]].tolist() == want  # sorted, so deterministic


# ---------------------------------------------------------------------------- distance, sign, normal

@pytest.mark.parametrize("name", ["torus", "icosphere", "box"])
def test_closed_mesh_signed_distance_matches_brute_force(name, rng):
    mesh = {"torus": torus, "icosphere": lambda: trimesh.creation.icosphere(subdivisions=2, radius=0.6),
            "box": lambda: trimesh.creation.box(extents=(1.0, 0.6, 0.8))}[name]()
    collider = tc.TriangleMesh(mesh, cell_size=0.08)
    assert collider.closed
    tris = triangles_of(mesh.vertices, mesh.faces)
    points = rng.uniform(-1.0, 1.0, size=(1500, 3))
    if name == "box":
        # Lattice points share y and z with edges and vertices: rays along x graze them.
        g = np.linspace(-0.6, 0.6, 7)
        points = np.vstack([points, np.stack(np.meshgrid(g, g, g), axis=-1).reshape(-1, 3)])
    dist, closest = nearest(points, tris)
    inside = winding_number(points, tris) > 0.5
    want = np.where(inside, -dist, dist)
    phi, normal = collider.signed_distance(points), collider.normal(points)
    off_surface = dist > 1e-9  # lattice points on faces are on the surface: either sign
    assert np.all(np.sign(phi[off_surface]) == np.sign(want[off_surface]))
    assert np.max(np.abs(phi - want)) < PHI_TOL  # exact at every range
    # The normal is the unit outward direction to a closest point: stepping back by phi
    # along it lands on the surface (also where several surface points are closest).
    assert np.allclose(np.linalg.norm(normal, axis=1), 1.0)
    assert np.max(nearest(points - phi[:, None] * normal, tris)[0]) < PHI_TOL
    unique = (dist > 1e-6) & (np.arange(len(points)) < 1500)  # random points: ties have measure 0
    want_n = np.where(inside[:, None], -1.0, 1.0) * (points - closest) / np.maximum(dist, 1e-300)[:, None]
    assert np.max(np.abs(normal[unique] - want_n[unique])) < NORMAL_TOL


def test_open_mesh_distance_is_unsigned_and_the_normal_faces_the_point(rng):
    mesh = bowl()
    collider = tc.TriangleMesh(mesh, thickness=0.01)
    assert not collider.closed
    tris = triangles_of(mesh.vertices, mesh.faces)
    points = rng.uniform(-0.7, 0.7, size=(1500, 3))
    dist, closest = nearest(points, tris)
    phi, normal = collider.signed_distance(points), collider.normal(points)
    assert np.max(np.abs(phi - (dist - 0.005))) < PHI_TOL  # a shell 0.01 m thick
    away = dist > 1e-6
    want_n = (points - closest) / np.maximum(dist, 1e-300)[:, None]
    assert np.max(np.abs(normal[away] - want_n[away])) < NORMAL_TOL


def test_distance_far_outside_the_grid_is_exact(rng):
    """Hundreds of cells off the mesh the query still returns the true distance (the box
    tree finishes what the cells cannot), positive for a closed mesh."""
    mesh = torus()
    collider = tc.TriangleMesh(mesh, cell_size=0.02)
    dirs = rng.normal(size=(200, 3))
    points = 3.0 * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    dist, _ = nearest(points, triangles_of(mesh.vertices, mesh.faces))
    phi = collider.signed_distance(points)
    assert np.all(phi > 0.0)
    assert np.max(np.abs(phi - dist)) < PHI_TOL


def test_moved_and_rotated_mesh_queries_follow_the_pose(rng):
    """The local frame's origin is the center of the mesh's bounds; `center` and `rotation`
    pose it, the same as moving the vertices."""
    mesh = torus()
    shift = np.array([0.3, -1.2, 2.0])
    R = tc.rotation_matrix((1.0, 2.0, -0.5), 0.7)
    a = tc.TriangleMesh(mesh, cell_size=0.1)
    b = tc.TriangleMesh((mesh.vertices + shift, mesh.faces), cell_size=0.1)
    c = tc.TriangleMesh(mesh, cell_size=0.1, center=shift, rotation=R)
    points = rng.uniform(-1, 1, size=(300, 3))
    assert np.allclose(b.center - a.center, shift)
    assert np.max(np.abs(a.signed_distance(points) - b.signed_distance(points + shift))) < 1e-12
    moved = shift + points @ R.T
    assert np.max(np.abs(a.signed_distance(points) - c.signed_distance(moved))) < 1e-12
    assert np.max(np.abs(a.normal(points) @ R.T - c.normal(moved))) < 1e-9


# ---------------------------------------------------------------------------- crossing

def segments_through(rng, count, scale):
    """Segments from random points to random points: crossings, grazes and misses."""
    x0 = rng.uniform(-scale, scale, size=(count, 3))
    x1 = rng.uniform(-scale, scale, size=(count, 3))
    return x0, x1


@pytest.mark.parametrize("name", ["bowl", "torus"])
@pytest.mark.parametrize("radius", [0.0, 0.03])
def test_crossing_first_contact_matches_the_swept_sphere_oracle(name, radius, rng):
    mesh = bowl() if name == "bowl" else torus()
    collider = tc.TriangleMesh(mesh, cell_size=0.07)
    tris = triangles_of(mesh.vertices, mesh.faces)
    x0, x1 = segments_through(rng, 120, 0.8)
    x1[:40] = x0[:40] + 0.05 * (x1[:40] - x0[:40])  # short steps, like a substep
    if collider.closed:  # from outside: a start inside a solid is a contact at t = 0
        outside = collider.signed_distance(x0) > radius
        x0, x1 = x0[outside], x1[outside]
    hit, t, n = collider.crossing(x0, x1, radius=radius)
    if radius == 0.0:
        want = segment_first_hit(x0, x1, tris)
    else:
        want = swept_contact(x0, x1, radius, tris)
    assert np.array_equal(hit, np.isfinite(want))
    assert np.max(np.abs(t[hit] - want[hit]), initial=0.0) < T_TOL
    assert np.all(t[~hit] == 1.0)
    # The normal at contact: from the surface toward the particle's center.
    contact = x0[hit] + t[hit, None] * (x1[hit] - x0[hit])
    dist, closest = nearest(contact, tris)
    if radius > 0:
        later = t[hit] > 0.0  # t = 0: the start is already within reach
        assert later.sum() > 20
        assert np.max(np.abs(dist[later] - radius)) < 1e-9
        assert np.max(np.abs(n[hit][later] - (contact - closest)[later] / radius)) < 1e-7
        assert np.all(dist[~later] <= radius)
    else:
        # On the surface itself: the face normal, on the start's side.
        assert np.all(np.einsum("ij,ij->i", n[hit], x0[hit] - contact) > 0)


def test_crossing_starts_in_contact_or_inside_a_closed_mesh(rng):
    collider = tc.TriangleMesh(trimesh.creation.box(extents=(1.0, 1.0, 1.0)))
    x0 = np.array([[0.0, 0.0, 0.0], [0.0, 0.52, 0.0], [0.0, 2.0, 0.0]])
    x1 = x0 + np.array([0.1, 0.0, 0.0])
    hit, t, n = collider.crossing(x0, x1, radius=0.05)
    assert hit.tolist() == [True, True, False]
    assert t[:2].tolist() == [0.0, 0.0]
    assert np.allclose(n[1], [0, 1, 0])


def test_fast_segment_through_a_sheet_hits_it_from_either_side():
    collider = tc.TriangleMesh(sheet(n=4))
    x0 = np.array([[0.13, 0.5, -0.21], [0.13, -0.5, -0.21], [0.5, 0.02, 0.5]])
    x1 = np.array([[0.13, -0.5, -0.21], [0.13, 0.5, -0.21], [0.5, -0.02, 0.5]])  # the last along a shared edge
    hit, t, n = collider.crossing(x0, x1, radius=0.01)
    assert hit.all()
    assert np.allclose(t, [0.49, 0.49, 0.25])
    assert np.allclose(n, [[0, 1, 0], [0, -1, 0], [0, 1, 0]])


# ---------------------------------------------------------------------------- physics

SPEED = 50.0  # m/s
RADIUS = 0.005


def test_a_zero_thickness_sheet_stops_fast_particles_from_both_sides(rng):
    """50 m/s is 4 cm per substep, eight radii: interference alone would let most through."""
    s = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=1.0 / 1200.0, substeps=10)
    s.add_collider(tc.TriangleMesh(sheet(n=6)), material=tc.Material(restitution=0.5, friction=0.0))
    n = 400
    side = rng.choice([-1.0, 1.0], size=n)
    x = np.column_stack([rng.uniform(-0.9, 0.9, n), 0.3 * side, rng.uniform(-0.9, 0.9, n)])
    v = np.column_stack([rng.uniform(-3, 3, n), -SPEED * side, rng.uniform(-3, 3, n)])
    s.add_particles(positions=x, velocities=v, radius=RADIUS)
    s.step(frames=2)
    y, vy = s.positions()[:, 1], s.velocities()[:, 1]
    assert np.all(np.sign(y) == side), "a particle passed through the sheet"
    assert np.all(np.abs(y) >= RADIUS * (1 - 1e-3))
    assert np.allclose(vy, 0.5 * SPEED * side)  # rebounded with e = 0.5
    assert s.stats()["failsafe"] == 0


def test_a_rising_sheet_carries_resting_particles():
    """Moving meshes: the surface velocity enters the response (e = 0, no friction)."""
    s = tc.Scene(gravity=(0.0, -9.81, 0.0), dt=1.0 / 1200.0, substeps=10)
    lift = 2.0
    s.add_collider(tc.TriangleMesh(sheet(n=4)), material=tc.Material(restitution=0.0, friction=0.0),
                   velocity=(0.0, lift, 0.0))
    x = np.array([[0.1, RADIUS, 0.2], [-0.4, RADIUS, 0.3]])
    s.add_particles(positions=x, radius=RADIUS)
    s.step(frames=3)
    y = s.positions()[:, 1]
    sheet_y = lift * s.time
    assert np.all(y > sheet_y)
    assert np.allclose(y, sheet_y + RADIUS, atol=1e-3)
    assert np.allclose(s.velocities()[:, 1], lift, atol=0.05)


def test_particles_dropped_into_an_open_bowl_stay_in_it(rng):
    s = tc.Scene(gravity=(0.0, -9.81, 0.0), dt=1.0 / 1200.0, substeps=10)
    s.add_collider(tc.TriangleMesh(bowl()), material=tc.Material(restitution=0.3, friction=0.2))
    n = 200
    x = np.column_stack([rng.uniform(-0.25, 0.25, n), rng.uniform(0.1, 0.3, n), rng.uniform(-0.25, 0.25, n)])
    s.add_particles(positions=x, radius=0.01)
    s.step(frames=40)
    p = s.positions()
    assert np.all(np.linalg.norm(p, axis=1) < 0.5), "a particle left through the bowl"
    assert np.all(p[:, 1] < 0.0)


def test_particles_inside_a_hollow_ball_stay_inside(rng):
    """closed=False: a closed mesh as a surface, here a container."""
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    s = tc.Scene(gravity=(0.0, -9.81, 0.0), dt=1.0 / 1200.0, substeps=10)
    s.add_collider(tc.TriangleMesh(ball, closed=False), material=tc.Material(restitution=0.8, friction=0.0))
    x = rng.uniform(-0.2, 0.2, size=(200, 3))
    v = rng.normal(scale=10.0, size=(200, 3))
    s.add_particles(positions=x, velocities=v, radius=0.01)
    for _ in range(10):
        s.step()
        assert np.all(np.linalg.norm(s.positions(), axis=1) < 0.5)


# ---------------------------------------------------------------------------- validation

def test_bad_input_names_the_argument(tmp_path):
    V, F = sheet(n=1)
    with pytest.raises(FileNotFoundError, match="mesh file not found"):
        tc.TriangleMesh(tmp_path / "missing.obj")
    bad = tmp_path / "bad.obj"
    bad.write_text("this is not a mesh\n")
    with pytest.raises(ValueError, match="mesh"):
        tc.TriangleMesh(bad)
    with pytest.raises(ValueError, match="faces must index"):
        tc.TriangleMesh((V, F + 100))
    with pytest.raises(ValueError, match="vertices must have shape"):
        tc.TriangleMesh((V[:, :2], F))
    with pytest.raises(TypeError, match="faces must be integer"):
        tc.TriangleMesh((V, F.astype(float)))
    with pytest.raises(ValueError, match="thickness must be >= 0"):
        tc.TriangleMesh((V, F), thickness=-0.1)
    with pytest.raises(ValueError, match="cell_size must be > 0"):
        tc.TriangleMesh((V, F), cell_size=0.0)
    with pytest.raises(ValueError, match="cell_size"):
        tc.TriangleMesh((V, F), cell_size=1e-5)
    with pytest.raises(ValueError, match="closed=True"):
        tc.TriangleMesh((V, F), closed=True)
    with pytest.raises(ValueError, match="thickness > 0 makes a shell"):
        tc.TriangleMesh(trimesh.creation.box(), closed=True, thickness=0.1)
    with pytest.raises(ValueError, match="rotation must be orthonormal"):
        tc.TriangleMesh((V, F), rotation=2 * np.eye(3))
    with pytest.raises(TypeError, match="mesh must be"):
        tc.TriangleMesh(42)


def test_mesh_from_a_file(tmp_path):
    path = tmp_path / "box.stl"
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).export(path)
    collider = tc.TriangleMesh(path)
    assert collider.closed and collider.triangle_count == 12
    assert np.allclose(collider.signed_distance([[0, 0, 0], [0, 1.0, 0]]), [-0.5, 0.5])
