"""tc.HeightField against closed-form terrains and NumPy oracles (tests/triangle_oracle.py):
a planar slope (which the triangles represent exactly), a sinusoid h = A sin(kx) cos(kz)
(within the interpolation error, and exactly against its triangles), the incline law for a
particle on a slope, terrains from image files, and argument checks.

The session runs in f64 (tests/conftest.py).
"""

import numpy as np
import pytest

import tai_coll as tc
from conftest import G
from triangle_oracle import nearest, segment_first_hit, swept_contact

PHI_TOL = 1e-9
T_TOL = 1e-6


def field_triangles(heights, dx, dz, origin, skirt=0.0):
    """The terrain's triangles as documented: cell (i, j) is (00, 10, 11) and (00, 01, 11).
    skirt > 0 adds the flat continuation beyond the footprint out to that distance (m): the
    border rows and columns drawn out as strips, the corner heights as flat squares."""
    nx, nz = heights.shape
    x, z = origin[0] + dx * np.arange(nx), origin[2] + dz * np.arange(nz)
    if skirt > 0.0:  # one more vertex beyond each side, at the border's height
        x = np.concatenate([[x[0] - skirt], x, [x[-1] + skirt]])
        z = np.concatenate([[z[0] - skirt], z, [z[-1] + skirt]])
        heights = np.pad(heights, 1, mode="edge")
    X, Z = np.meshgrid(x, z, indexing="ij")
    P = np.stack([X, origin[1] + heights, Z], axis=-1)
    p00, p10, p01, p11 = P[:-1, :-1], P[1:, :-1], P[:-1, 1:], P[1:, 1:]
    lower = np.stack([p00, p10, p11], axis=-2).reshape(-1, 3, 3)
    upper = np.stack([p00, p01, p11], axis=-2).reshape(-1, 3, 3)
    return np.concatenate([lower, upper])


def sinusoid(A=0.2, k=3.0, cells=24, size=2.0, origin=(-1.0, 0.5, -1.0)):
    dx = size / cells
    x = origin[0] + dx * np.arange(cells + 1)
    z = origin[2] + dx * np.arange(cells + 1)
    heights = A * np.sin(k * x)[:, None] * np.cos(k * z)[None, :]
    return heights, dx, np.asarray(origin, float)


def slope(angle, cells=10, size=2.0, origin=(-1.0, 0.0, -1.0)):
    """Heights of the plane y = -tan(angle) x (falling toward +x)."""
    dx = size / cells
    x = origin[0] + dx * np.arange(cells + 1)
    heights = np.repeat((-np.tan(angle) * x)[:, None], cells + 1, axis=1)
    return heights, dx, np.asarray(origin, float)


def vertical_hits(field, xz, top=10.0):
    """The terrain's height under each (x, z), from the kernels' own crossing of a falling point."""
    starts = np.column_stack([xz[:, 0], np.full(len(xz), top), xz[:, 1]])
    ends = starts * np.array([1.0, -1.0, 1.0])
    hit, t, _ = field.crossing(starts, ends, radius=0.0)
    assert hit.all()
    return top - 2.0 * top * t


# ---------------------------------------------------------------------------- queries

def test_planar_slope_is_exact(rng):
    angle = np.radians(25.0)
    heights, dx, origin = slope(angle)
    field = tc.HeightField(heights=heights, cell_size=dx, origin=origin)
    n = np.array([np.sin(angle), np.cos(angle), 0.0])  # outward normal of y = -tan(a) x
    # Points whose closest surface point lies well inside the footprint.
    p = np.column_stack([rng.uniform(-0.6, 0.6, 500), np.zeros(500), rng.uniform(-0.6, 0.6, 500)])
    p[:, 1] = -np.tan(angle) * p[:, 0] + rng.uniform(-0.3, 0.3, 500)
    want = (p - np.array([0.0, origin[1], 0.0])) @ n
    assert np.max(np.abs(field.signed_distance(p) - want)) < PHI_TOL
    assert np.max(np.abs(field.normal(p) - n)) < 1e-9


def test_sinusoid_heights_match_the_closed_form_within_interpolation_error(rng):
    """h = A sin(kx) cos(kz): the triangles interpolate it with error O(dx^2 A k^2)."""
    xz = rng.uniform(-0.95, 0.95, size=(400, 2))
    exact = 0.5 + 0.2 * np.sin(3.0 * xz[:, 0]) * np.cos(3.0 * xz[:, 1])
    errors = []
    for cells in (12, 24, 48):
        heights, dx, origin = sinusoid(cells=cells)
        field = tc.HeightField(heights=heights, cell_size=dx, origin=origin)
        y = vertical_hits(field, xz)
        assert np.max(np.abs(y - field.height(xz[:, 0], xz[:, 1]))) < 1e-12  # host and kernel agree
        errors.append(np.max(np.abs(y - exact)))
        assert errors[-1] < 0.2 * 9.0 * dx * dx  # A k^2 dx^2
    assert errors[1] < errors[0] / 3.0 and errors[2] < errors[1] / 3.0  # second order


def test_sinusoid_signed_distance_matches_its_triangles(rng):
    heights, dx, origin = sinusoid()
    field = tc.HeightField(heights=heights, cell_size=dx, origin=origin)
    tris = field_triangles(heights, dx, dx, origin)
    xz = rng.uniform(-0.8, 0.8, size=(800, 2))
    y = field.height(xz[:, 0], xz[:, 1]) + rng.uniform(-0.15, 0.15, 800)
    p = np.column_stack([xz[:, 0], y, xz[:, 1]])
    dist, closest = nearest(p, tris)
    below = p[:, 1] < field.height(p[:, 0], p[:, 2])
    phi, normal = field.signed_distance(p), field.normal(p)
    assert np.max(np.abs(phi - np.where(below, -dist, dist))) < PHI_TOL
    # The normal: unit, outward; stepping back by phi along it lands on the terrain.
    assert np.allclose(np.linalg.norm(normal, axis=1), 1.0)
    assert np.max(nearest(p - phi[:, None] * normal, tris)[0]) < PHI_TOL


def test_far_above_the_terrain_phi_is_exact(rng):
    """Many cells above the terrain (and beside it, over the flat continuation) phi is the
    true distance, not a lower bound: a particle that large must rest on the surface."""
    heights, dx, origin = sinusoid()
    field = tc.HeightField(heights=heights, cell_size=dx, origin=origin)
    tris = field_triangles(heights, dx, dx, origin, skirt=20.0)
    p = np.column_stack([rng.uniform(-1.5, 1.5, 300), rng.uniform(1.0, 3.0, 300), rng.uniform(-1.5, 1.5, 300)])
    dist, _ = nearest(p, tris)
    assert np.max(np.abs(field.signed_distance(p) - dist)) < PHI_TOL


def test_beyond_the_footprint_the_border_continues_flat(rng):
    angle = np.radians(20.0)
    heights, dx, origin = slope(angle)
    field = tc.HeightField(heights=heights, cell_size=dx, origin=origin)
    x_end = origin[0] + dx * (heights.shape[0] - 1)
    y_end = heights[-1, 0]
    p = np.column_stack([rng.uniform(x_end + 0.5, x_end + 3.0, 100), y_end + rng.uniform(-0.05, 0.05, 100),
                         rng.uniform(-0.9, 0.9, 100)])
    assert np.max(np.abs(field.signed_distance(p) - (p[:, 1] - y_end))) < PHI_TOL
    assert np.allclose(field.normal(p), [0.0, 1.0, 0.0])


@pytest.mark.parametrize("radius", [0.0, 0.04])
def test_crossing_matches_the_swept_sphere_oracle(radius, rng):
    heights, dx, origin = sinusoid(cells=16)
    field = tc.HeightField(heights=heights, cell_size=dx, origin=origin)
    tris = field_triangles(heights, dx, dx, origin)
    n = 100
    x0 = np.column_stack([rng.uniform(-0.7, 0.7, n), rng.uniform(0.5, 1.0, n), rng.uniform(-0.7, 0.7, n)])
    x1 = x0 + rng.uniform(-0.3, 0.3, size=(n, 3)) - np.array([0.0, 0.3, 0.0])
    x1[:30] = x0[:30] + 0.1 * (x1[:30] - x0[:30])  # short steps, like a substep
    starts_clear = field.signed_distance(x0) > radius
    x0, x1 = x0[starts_clear], x1[starts_clear]
    hit, t, normal = field.crossing(x0, x1, radius=radius)
    want = swept_contact(x0, x1, radius, tris) if radius > 0.0 else segment_first_hit(x0, x1, tris)
    assert hit.sum() > 20 and (~hit).sum() > 5
    assert np.array_equal(hit, np.isfinite(want))
    assert np.max(np.abs(t[hit] - want[hit])) < T_TOL
    contact = x0[hit] + t[hit, None] * (x1[hit] - x0[hit])
    dist, closest = nearest(contact, tris)
    if radius > 0.0:
        assert np.max(np.abs(normal[hit] - (contact - closest) / radius)) < 1e-7
    assert np.all(normal[hit, 1] > 0.0)  # from above: facing up


def test_crossing_from_below_reports_contact_at_the_start():
    heights, dx, origin = sinusoid()
    field = tc.HeightField(heights=heights, cell_size=dx, origin=origin)
    hit, t, _ = field.crossing([[0.1, -1.0, 0.2]], [[0.1, -1.1, 0.2]])
    assert hit[0] and t[0] == 0.0


# ---------------------------------------------------------------------------- physics

def resting_on_slope(angle, friction, frames):
    """A particle released at rest on the slope y = -tan(angle) x; returns (distance slid
    along the slope, elapsed time)."""
    heights, dx, origin = slope(angle, cells=8, size=8.0, origin=(-4.0, 0.0, -4.0))
    s = tc.Scene(gravity=(0.0, -G, 0.0), dt=1.0 / 1200.0, substeps=10)
    s.add_collider(tc.HeightField(heights=heights, cell_size=dx, origin=origin),
                   material=tc.Material(restitution=0.0, friction=friction))
    r = 0.01
    normal = np.array([np.sin(angle), np.cos(angle), 0.0])
    start = np.array([-2.0, np.tan(angle) * 2.0, 0.3]) + r * normal
    s.add_particles(positions=[start], radius=r)
    s.step(frames=frames)
    moved = s.positions()[0] - start
    assert abs(moved @ normal) < 1e-3 * r + 1e-9 or moved @ normal > 0  # never into the terrain
    return moved @ np.array([np.cos(angle), -np.sin(angle), 0.0]), s.time


def test_incline_law_holds_with_static_friction():
    angle = np.radians(20.0)
    slid, _ = resting_on_slope(angle, friction=0.5, frames=30)  # mu > tan(20 deg) = 0.36
    assert abs(slid) < 1e-6


def test_incline_law_slides_with_kinetic_friction():
    """mu < tan(angle): s = a t^2 / 2 with a = g (sin - mu cos)."""
    angle = np.radians(30.0)
    mu = 0.2
    slid, t = resting_on_slope(angle, friction=mu, frames=30)
    expected = 0.5 * G * (np.sin(angle) - mu * np.cos(angle)) * t * t
    assert slid == pytest.approx(expected, rel=0.02)


# ---------------------------------------------------------------------------- images and validation

def write_pgm(path, image, binary=True):
    h, w = image.shape
    if binary:
        path.write_bytes(b"P5\n# a comment\n%d %d\n255\n" % (w, h) + image.astype(np.uint8).tobytes())
    else:
        body = "\n".join(" ".join(str(int(v)) for v in row) for row in image)
        path.write_text(f"P2\n{w} {h}\n255\n{body}\n")


def test_terrain_from_image_files(tmp_path):
    image = np.arange(12, dtype=np.uint8).reshape(3, 4) * 20  # 3 rows (z), 4 columns (x)
    for name, binary in (("t.pgm", True), ("t_ascii.pgm", False)):
        write_pgm(tmp_path / name, image, binary)
        field = tc.HeightField.from_image(tmp_path / name, cell_size=0.5, height_scale=2.0)
        assert field.heights.shape == (4, 3)
        assert np.allclose(field.heights, image.T / 255.0 * 2.0)
    rgb = np.repeat(image[:, :, None], 3, axis=2)
    (tmp_path / "t.ppm").write_bytes(b"P6 4 3 255\n" + rgb.tobytes())
    assert np.allclose(tc.HeightField.from_image(tmp_path / "t.ppm", cell_size=1.0).heights, image.T / 255.0)
    np.save(tmp_path / "t.npy", image.astype(float))
    field = tc.HeightField.from_image(tmp_path / "t.npy", cell_size=1.0, height_scale=0.01, origin=(1, 2, 3))
    assert np.allclose(field.heights, image.T * 0.01)
    assert field.height(1.0, 3.0) == pytest.approx(2.0)


def test_bad_input_names_the_argument(tmp_path):
    good = np.zeros((3, 3))
    with pytest.raises(ValueError, match="heights must be a 2-D array"):
        tc.HeightField(heights=np.zeros(5), cell_size=1.0)
    with pytest.raises(ValueError, match="heights must be a 2-D array"):
        tc.HeightField(heights=np.zeros((1, 4)), cell_size=1.0)
    with pytest.raises(ValueError, match="heights must be finite"):
        tc.HeightField(heights=np.array([[0.0, np.nan], [0.0, 0.0]]), cell_size=1.0)
    with pytest.raises(ValueError, match="cell_size must be > 0"):
        tc.HeightField(heights=good, cell_size=0.0)
    with pytest.raises(ValueError, match=r"cell_size\[1\] must be > 0"):
        tc.HeightField(heights=good, cell_size=(1.0, -1.0))
    with pytest.raises(ValueError, match="origin must have 3 components"):
        tc.HeightField(heights=good, cell_size=1.0, origin=(0, 0))
    with pytest.raises(FileNotFoundError, match="height image not found"):
        tc.HeightField.from_image(tmp_path / "missing.pgm", cell_size=1.0)
    (tmp_path / "bad.pgm").write_bytes(b"GIF89a")
    with pytest.raises(ValueError, match="not a PGM/PPM image"):
        tc.HeightField.from_image(tmp_path / "bad.pgm", cell_size=1.0)
    np.save(tmp_path / "cube.npy", np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match="2-D array"):
        tc.HeightField.from_image(tmp_path / "cube.npy", cell_size=1.0)
