"""Geometry queries (docs/physics.md 1) against independent numpy references.

Every reference below is a closed-form signed distance written here from the textbook
formulas, in numpy; nothing from tai_coll is used as an oracle. The session runs in f64
(tests/conftest.py), so signed distances must agree to 1e-9.
"""

import numpy as np
import pytest

import tai_coll as tc

PHI_TOL = 1e-9        # signed distance, normal length, closest-point projection (f64)
GRAD_STEP = 1e-7      # central-difference step of the reference gradient
NORMAL_TOL = 1e-6     # normal against the reference gradient
SMOOTH_MARGIN = 2e-3  # distance kept from kinks (medial axis, surface, edges) for gradient checks
T_TOL = 1e-4          # crossing fraction by root finding


# ---------------------------------------------------------------------------- references

def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def ref_plane(x, point, normal):
    return (x - np.asarray(point, float)) @ unit(normal)


def ref_sphere(x, center, radius):
    return np.linalg.norm(x - np.asarray(center, float), axis=1) - radius


def ref_box_q(x, center, half, rotation):
    """q = |p| - h with p = R^T (x - c) the local point."""
    p = (x - np.asarray(center, float)) @ np.asarray(rotation, float)
    return np.abs(p) - np.asarray(half, float)


def ref_box(x, center, half, rotation):
    # |max(q, 0)| + min(max_i q_i, 0)
    q = ref_box_q(x, center, half, rotation)
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def ref_axial(x, center, axis):
    """(coordinate along the unit axis, distance from the axis line)."""
    a = unit(axis)
    d = x - np.asarray(center, float)
    along = d @ a
    rho = np.linalg.norm(d - along[:, None] * a, axis=1)
    return along, rho


def ref_cylinder_d(x, center, radius, half_height, axis):
    along, rho = ref_axial(x, center, axis)
    return rho - radius, np.abs(along) - half_height


def ref_cylinder(x, center, radius, half_height, axis):
    # 2-D box SDF in (rho, |y|): min(max(dr, dy), 0) + |max((dr, dy), 0)|
    dr, dy = ref_cylinder_d(x, center, radius, half_height, axis)
    return np.minimum(np.maximum(dr, dy), 0.0) + np.hypot(np.maximum(dr, 0.0), np.maximum(dy, 0.0))


def ref_segment_distance(x, a, b):
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    ab = b - a
    s = np.clip((x - a) @ ab / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(x - (a + s[:, None] * ab), axis=1)


def ref_capsule(x, a, b, radius):
    return ref_segment_distance(x, a, b) - radius


def ref_gradient(phi, x, h=GRAD_STEP):
    """Central differences of a reference SDF, one axis at a time."""
    grad = np.zeros_like(x)
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        grad[:, k] = (phi(x + e) - phi(x - e)) / (2 * h)
    return grad


def orthonormal_frame(axis):
    """Columns (u, a, w): a right-handed frame whose second column is the unit axis.
    Independent of tai_coll's align_y; used only to place sample points."""
    a = unit(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    u = unit(np.cross(a, helper))
    w = np.cross(u, a)
    return np.column_stack([u, a, w])


# ---------------------------------------------------------------------------- shapes

class Case:
    """A collider, its numpy reference phi, and where to sample it."""

    def __init__(self, name, collider, phi, center, frame, extent, features, smooth):
        self.name = name
        self.collider = collider
        self.phi = phi
        self.center = np.asarray(center, float)
        self.frame = np.asarray(frame, float)  # local -> world, only for placing samples
        self.extent = float(extent)
        self.features = np.asarray(features, float)  # local points on edges, caps, faces
        self.smooth = smooth  # x -> mask of points where phi is differentiable (with margin)

    def to_world(self, local):
        return self.center + local @ self.frame.T

    def points(self, rng, n_uniform=300, per_feature=6):
        uniform = self.center + rng.uniform(-1.6, 1.6, size=(n_uniform, 3)) * self.extent
        near = []
        for sigma in (1e-2, 1e-4):
            jitter = rng.normal(scale=sigma, size=(len(self.features), per_feature, 3))
            near.append((self.features[:, None, :] + jitter).reshape(-1, 3))
        return np.vstack([uniform, self.to_world(np.vstack([self.features] + near))])


def ring(radius, y, count=12):
    ang = np.linspace(0, 2 * np.pi, count, endpoint=False)
    return np.column_stack([radius * np.cos(ang), np.full(count, y), radius * np.sin(ang)])


def sphere_case():
    c, R = np.array([0.3, -0.2, 0.5]), 0.7
    rng = np.random.default_rng(1)
    dirs = rng.normal(size=(24, 3))
    feats = R * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    return Case("sphere", tc.Sphere(center=c, radius=R), lambda x: ref_sphere(x, c, R), c, np.eye(3),
                R, feats, lambda x: np.linalg.norm(x - c, axis=1) > SMOOTH_MARGIN)


def box_case(name, center, half, rotation):
    center, half = np.asarray(center, float), np.asarray(half, float)
    rot = np.eye(3) if rotation is None else rotation
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    corners = signs * half
    edges = np.vstack([signs * half * m for m in (np.array([0, 1, 1]), np.array([1, 0, 1]), np.array([1, 1, 0]))])
    faces = np.vstack([np.diag(half), -np.diag(half)])
    on_faces = faces + np.array([0.3, -0.2, 0.1]) * half * (faces == 0)  # off-center face points
    feats = np.vstack([corners, edges, faces, on_faces])

    def phi(x):
        return ref_box(x, center, half, rot)

    def smooth(x):
        q = np.sort(ref_box_q(x, center, half, rot), axis=1)
        d = phi(x)
        inside_ok = (d < -SMOOTH_MARGIN) & (q[:, 2] - q[:, 1] > SMOOTH_MARGIN)
        return (d > SMOOTH_MARGIN) | inside_ok

    kwargs = {} if rotation is None else {"rotation": rotation}
    return Case(name, tc.Box(center=center, half_extents=half, **kwargs), phi, center, rot,
                half.max(), feats, smooth)


def cylinder_case(name, center, radius, half_height, axis):
    center = np.asarray(center, float)
    kwargs = {} if axis is None else {"axis": axis}
    axis = (0.0, 1.0, 0.0) if axis is None else axis
    feats = np.vstack([ring(radius, half_height), ring(radius, -half_height), ring(radius, 0.3 * half_height),
                       ring(0.5 * radius, half_height), ring(0.5 * radius, -half_height),
                       [[0, half_height, 0], [0, -half_height, 0]]])

    def phi(x):
        return ref_cylinder(x, center, radius, half_height, axis)

    def smooth(x):
        dr, dy = ref_cylinder_d(x, center, radius, half_height, axis)
        along, rho = ref_axial(x, center, axis)
        d = phi(x)
        inside_ok = ((d < -SMOOTH_MARGIN) & (np.abs(dr - dy) > SMOOTH_MARGIN) & (rho > SMOOTH_MARGIN)
                     & (np.abs(along) > SMOOTH_MARGIN))
        return (d > SMOOTH_MARGIN) | inside_ok

    return Case(name, tc.Cylinder(center=center, radius=radius, half_height=half_height, **kwargs), phi,
                center, orthonormal_frame(axis), max(radius, half_height), feats, smooth)


def capsule_case(name, collider, a, b, radius):
    a, b = np.asarray(a, float), np.asarray(b, float)
    center = (a + b) / 2
    h = np.linalg.norm(b - a) / 2
    feats = np.vstack([ring(radius, h), ring(radius, -h), ring(radius, 0.2 * h),
                       [[0, h + radius, 0], [0, -h - radius, 0], [0, h, 0], [0, -h, 0]]])

    def phi(x):
        return ref_capsule(x, a, b, radius)

    def smooth(x):
        return ref_segment_distance(x, a, b) > SMOOTH_MARGIN

    return Case(name, collider, phi, center, orthonormal_frame(b - a), h + radius, feats, smooth)


def capsule_from_axis(name, center, radius, half_height, axis):
    center = np.asarray(center, float)
    a = center - half_height * unit(axis)
    b = center + half_height * unit(axis)
    return capsule_case(name, tc.Capsule(center=center, radius=radius, half_height=half_height, axis=axis),
                        a, b, radius)


def capsule_from_endpoints():
    a, b = np.array([-0.5, 0.2, 0.1]), np.array([0.4, -0.3, 0.6])
    return capsule_case("capsule_from_endpoints", tc.Capsule.from_endpoints(a, b, radius=0.2), a, b, 0.2)


CASES = {
    "sphere": sphere_case,
    "box_axis_aligned": lambda: box_case("box_axis_aligned", (0.1, 0.2, -0.3), (0.5, 0.3, 0.8), None),
    "box_rotated": lambda: box_case("box_rotated", (-0.4, 0.3, 0.2), (0.6, 0.2, 0.4),
                                    tc.rotation_matrix((1.0, 2.0, -0.5), 0.7)),
    "cylinder_default_axis": lambda: cylinder_case("cylinder_default_axis", (0.2, 0.1, -0.1), 0.4, 0.6, None),
    "cylinder_tilted_axis": lambda: cylinder_case("cylinder_tilted_axis", (0.1, -0.3, 0.4), 0.3, 0.5,
                                                  (1.0, 1.0, 0.3)),
    "cylinder_axis_minus_z": lambda: cylinder_case("cylinder_axis_minus_z", (0.0, 0.5, 0.0), 0.5, 0.25,
                                                   (0.0, 0.0, -1.0)),
    "capsule_default_axis": lambda: capsule_from_axis("capsule_default_axis", (0.0, 0.0, 0.0), 0.25, 0.5,
                                                      (0.0, 1.0, 0.0)),
    "capsule_tilted_axis": lambda: capsule_from_axis("capsule_tilted_axis", (0.3, -0.1, 0.2), 0.3, 0.4,
                                                     (0.2, 1.0, -0.4)),
    "capsule_axis_minus_y": lambda: capsule_from_axis("capsule_axis_minus_y", (0.1, 0.1, 0.1), 0.2, 0.3,
                                                      (0.0, -1.0, 0.0)),
    "capsule_from_endpoints": capsule_from_endpoints,
}
SOLIDS = sorted(CASES)
ROOT_FOUND = [name for name in SOLIDS if name != "sphere"]  # conservative advancement shapes


@pytest.fixture(params=SOLIDS)
def case(request):
    return CASES[request.param]()


# ---------------------------------------------------------------------------- signed distance, normal

PLANES = [
    ((0.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    ((0.5, -1.0, 2.0), (0.0, 0.0, -2.0)),    # non-unit, along -z
    ((1.0, 2.0, 3.0), (3.0, 4.0, 0.0)),      # non-unit, oblique
    ((-0.3, 0.2, 0.1), (1.0, -2.0, 0.5)),
    ((0.0, 1.0, 0.0), (0.0, -5.0, 0.0)),     # facing -y (a half turn of the local frame)
]


@pytest.mark.parametrize("point, normal", PLANES)
def test_plane_signed_distance_and_normal(point, normal, rng):
    plane = tc.Plane(point=point, normal=normal)
    x = np.asarray(point) + rng.uniform(-3, 3, size=(200, 3))
    phi = plane.signed_distance(x)
    n = plane.normal(x)
    np.testing.assert_allclose(phi, ref_plane(x, point, normal), atol=PHI_TOL, rtol=0)
    np.testing.assert_allclose(n, np.broadcast_to(unit(normal), n.shape), atol=PHI_TOL, rtol=0)
    assert (phi < 0).any() and (phi > 0).any()


@pytest.mark.parametrize("normal", [(1e-6, 1.0, 0.0), (0.0, -1.0, 2e-7), (3e-6, -1.0, -1e-6)])
def test_plane_normal_nearly_along_y(normal, rng):
    """A plane tilted by a micro-radian from +-y is still that plane, not the axis plane."""
    plane = tc.Plane(point=(0.0, 0.0, 0.0), normal=normal)
    x = rng.uniform(-10, 10, size=(50, 3))
    np.testing.assert_allclose(plane.normal(x)[0], unit(normal), atol=PHI_TOL, rtol=0)
    np.testing.assert_allclose(plane.signed_distance(x), ref_plane(x, (0, 0, 0), normal), atol=PHI_TOL, rtol=0)


def test_signed_distance_matches_closed_form(case, rng):
    x = case.points(rng)
    phi = case.collider.signed_distance(x)
    ref = case.phi(x)
    assert phi.shape == (len(x),)
    np.testing.assert_allclose(phi, ref, atol=PHI_TOL, rtol=0)
    # the sample set really covers both sides and the surface band
    assert (ref < -1e-3).sum() > 20 and (ref > 1e-3).sum() > 20 and (np.abs(ref) < 1e-3).sum() > 20


def test_normal_is_unit_gradient_pointing_outward(case, rng):
    x = case.points(rng)
    phi = case.collider.signed_distance(x)
    n = case.collider.normal(x)
    assert n.shape == (len(x), 3)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=PHI_TOL, rtol=0)

    # n is the gradient of phi wherever phi is differentiable
    smooth = case.smooth(x)
    assert smooth.sum() > 0.4 * len(x)
    grad = ref_gradient(case.phi, x[smooth])
    np.testing.assert_allclose(n[smooth], grad, atol=NORMAL_TOL, rtol=0)

    # n points from the closest surface point to x: stepping back by phi lands on the surface
    # (everywhere, medial axis included: any closest point will do there)
    np.testing.assert_allclose(case.phi(x - phi[:, None] * n), 0.0, atol=PHI_TOL, rtol=0)
    outside = phi > 1e-6
    assert outside.sum() > 20
    np.testing.assert_array_less(case.phi(x[outside]), case.phi(x[outside] + 1e-3 * n[outside]))


def test_capsule_from_endpoints_pose():
    a, b = np.array([1.0, -2.0, 0.5]), np.array([-1.0, 1.0, 2.5])
    cap = tc.Capsule.from_endpoints(a, b, radius=0.3)
    np.testing.assert_allclose(cap.center, (a + b) / 2, atol=1e-15)
    assert cap.half_height == pytest.approx(np.linalg.norm(b - a) / 2, abs=1e-15)
    np.testing.assert_allclose(cap.axis, unit(b - a), atol=1e-15)
    # the end caps are the half-spheres around a and b
    tips = np.array([a - 0.3 * unit(b - a), b + 0.3 * unit(b - a)])
    np.testing.assert_allclose(cap.signed_distance(tips), 0.0, atol=PHI_TOL)
    np.testing.assert_allclose(cap.signed_distance(np.array([a, b])), -0.3, atol=PHI_TOL)


# ---------------------------------------------------------------------------- guard cases

def assert_unit_finite(n):
    assert np.all(np.isfinite(n))
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=PHI_TOL, rtol=0)


def test_sphere_center_guard():
    c = np.array([0.3, -0.2, 0.5])
    sphere = tc.Sphere(center=c, radius=0.7)
    phi = sphere.signed_distance(c[None])
    n = sphere.normal(c[None])
    assert phi[0] == pytest.approx(-0.7, abs=PHI_TOL)
    assert_unit_finite(n)
    # the reported normal still leads to a closest surface point
    np.testing.assert_allclose(ref_sphere(c[None] - phi[:, None] * n, c, 0.7), 0.0, atol=PHI_TOL)


@pytest.mark.parametrize("axis", [(0.0, 1.0, 0.0), (1.0, 1.0, 0.3), (0.0, -1.0, 0.0)])
def test_capsule_axis_guard(axis):
    c = np.array([0.3, -0.1, 0.2])
    cap = tc.Capsule(center=c, radius=0.3, half_height=0.4, axis=axis)
    x = c + np.linspace(-0.4, 0.4, 9)[:, None] * unit(axis)  # on the axis segment, ends included
    phi = cap.signed_distance(x)
    n = cap.normal(x)
    np.testing.assert_allclose(phi, -0.3, atol=PHI_TOL)
    assert_unit_finite(n)
    np.testing.assert_allclose(n @ unit(axis), 0.0, atol=PHI_TOL)  # any radial direction is closest
    a, b = c - 0.4 * unit(axis), c + 0.4 * unit(axis)
    np.testing.assert_allclose(ref_capsule(x - phi[:, None] * n, a, b, 0.3), 0.0, atol=PHI_TOL)


@pytest.mark.parametrize("axis", [(0.0, 1.0, 0.0), (1.0, 1.0, 0.3), (0.0, 0.0, -1.0)])
def test_cylinder_axis_guard(axis):
    c = np.array([0.1, -0.3, 0.4])
    r, h = 0.3, 0.5
    cyl = tc.Cylinder(center=c, radius=r, half_height=h, axis=axis)
    along = np.array([-0.45, -0.3, -0.1, 0.0, 0.1, 0.25, 0.3, 0.45])  # side nearest for |y| < 0.2
    x = c + along[:, None] * unit(axis)
    phi = cyl.signed_distance(x)
    n = cyl.normal(x)
    np.testing.assert_allclose(phi, -np.minimum(r, h - np.abs(along)), atol=PHI_TOL)
    np.testing.assert_allclose(phi, ref_cylinder(x, c, r, h, axis), atol=PHI_TOL)
    assert_unit_finite(n)
    np.testing.assert_allclose(ref_cylinder(x - phi[:, None] * n, c, r, h, axis), 0.0, atol=PHI_TOL)


# ---------------------------------------------------------------------------- crossing: references

def ref_first_contact(phi, x0, x1, radius, samples=4001):
    """First t in [0, 1] with phi(x(t)) = radius: dense sampling, then bisection.
    Returns (hit, t, min over the samples of phi - radius)."""
    t = np.linspace(0.0, 1.0, samples)
    f = phi(x0 + t[:, None] * (x1 - x0)) - radius
    if f[0] < 0:
        return True, 0.0, f.min()
    below = np.flatnonzero(f < 0)
    if below.size == 0:
        return False, 1.0, f.min()
    lo, hi = t[below[0] - 1], t[below[0]]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if phi((x0 + mid * (x1 - x0))[None])[0] - radius < 0:
            hi = mid
        else:
            lo = mid
    return True, hi, f.min()


def random_segments(case, rng, count):
    """Starts outside at 1.5 to 3 extents. A third of the segments end inside the shape;
    the others end anywhere around it (inside, through and past it, or missing it)."""
    dirs = rng.normal(size=(count, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    starts = case.center + dirs * case.extent * rng.uniform(1.5, 3.0, size=(count, 1))
    targets = case.center + rng.uniform(-1.0, 1.0, size=(count, 3)) * case.extent
    ends = starts + (targets - starts) * rng.uniform(0.5, 2.5, size=(count, 1))
    pool = case.center + rng.uniform(-1.0, 1.0, size=(50 * count, 3)) * case.extent
    inside = pool[case.phi(pool) < -0.02][: count // 3]
    ends[: len(inside)] = inside
    return starts, ends


# ---------------------------------------------------------------------------- crossing: plane, sphere

@pytest.mark.parametrize("radius", [0.0, 0.05])
@pytest.mark.parametrize("point, normal", PLANES[1:4])
def test_plane_crossing_linear_t(point, normal, radius, rng):
    plane = tc.Plane(point=point, normal=normal)
    x0 = np.asarray(point) + rng.uniform(-2, 2, size=(300, 3))
    x1 = x0 + rng.uniform(-3, 3, size=(300, 3))
    hit, t, n = plane.crossing(x0, x1, radius)
    d0 = ref_plane(x0, point, normal) - radius
    d1 = ref_plane(x1, point, normal) - radius
    ref_hit = (d0 < 0) | (d1 < 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ref_t = np.where(d0 < 0, 0.0, np.where(d1 < 0, d0 / (d0 - d1), 1.0))
    np.testing.assert_array_equal(hit, ref_hit)
    np.testing.assert_allclose(t, ref_t, atol=1e-12, rtol=0)
    np.testing.assert_allclose(n[hit], np.broadcast_to(unit(normal), n[hit].shape), atol=PHI_TOL)
    crossed = hit & (d0 >= 0)
    assert crossed.sum() > 30 and (~hit).sum() > 30 and (d0 < 0).sum() > 30
    # the sphere of `radius` touches exactly: phi = radius at the contact
    xc = x0 + t[:, None] * (x1 - x0)
    np.testing.assert_allclose(ref_plane(xc[crossed], point, normal), radius, atol=1e-10)


def ref_sphere_t(x0, x1, center, R):
    """Smallest root in [0, 1] of |x0 + t d - c|^2 = R^2, via numpy.roots."""
    d = x1 - x0
    p = x0 - center
    if p @ p < R * R:
        return True, 0.0
    roots = np.roots([d @ d, 2 * p @ d, p @ p - R * R])
    roots = np.sort(roots[np.isreal(roots)].real)
    roots = roots[(roots >= 0) & (roots <= 1)]
    return (True, roots[0]) if roots.size else (False, 1.0)


@pytest.mark.parametrize("radius", [0.0, 0.1])
def test_sphere_crossing_quadratic_t(radius, rng):
    c, R = np.array([0.3, -0.2, 0.5]), 0.7
    sphere = tc.Sphere(center=c, radius=R)
    x0 = c + rng.uniform(-1.5, 1.5, size=(400, 3))
    x1 = c + rng.uniform(-2.5, 2.5, size=(400, 3))
    hit, t, n = sphere.crossing(x0, x1, radius)
    ref = [ref_sphere_t(a, b, c, R + radius) for a, b in zip(x0, x1)]
    ref_hit = np.array([h for h, _ in ref])
    ref_t = np.array([s for _, s in ref])
    np.testing.assert_array_equal(hit, ref_hit)
    np.testing.assert_allclose(t, ref_t, atol=1e-9, rtol=0)
    assert (ref_t[ref_hit] > 0).sum() > 30 and (~ref_hit).sum() > 30 and (ref_t[ref_hit] == 0).sum() > 5
    xc = x0 + t[:, None] * (x1 - x0)
    crossed = hit & (t > 0)
    np.testing.assert_allclose(ref_sphere(xc[crossed], c, R), radius, atol=1e-9)
    np.testing.assert_allclose(n[crossed], (xc[crossed] - c) / np.linalg.norm(xc[crossed] - c, axis=1)[:, None],
                               atol=1e-9)


@pytest.mark.parametrize("radius", [0.02, 0.1])
def test_sphere_and_plane_touch_at_radius_offset(radius):
    """A moving sphere of radius r touches when phi = r: a path whose closest approach is
    0.9 r hits, one at 1.1 r misses."""
    sphere = tc.Sphere(center=(0.0, 0.0, 0.0), radius=0.5)
    plane = tc.Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0))
    for gap, expect in ((0.9 * radius, True), (1.1 * radius, False)):
        y = 0.5 + gap
        hit, t, _ = sphere.crossing(np.array([[-2.0, y, 0.0]]), np.array([[2.0, y, 0.0]]), radius)
        assert hit[0] == expect
        if expect:
            x = -2.0 + 4.0 * t[0]
            assert np.hypot(x, y) == pytest.approx(0.5 + radius, abs=1e-9)
        else:
            assert t[0] == 1.0
        hit, t, _ = plane.crossing(np.array([[0.0, 1.0, 0.0]]), np.array([[0.3, gap, 0.1]]), radius)
        assert hit[0] == expect
        if expect:
            assert 1.0 + t[0] * (gap - 1.0) == pytest.approx(radius, abs=1e-12)


# ---------------------------------------------------------------------------- crossing: root finding

@pytest.mark.parametrize("radius", [0.0, 0.02, 0.04])
@pytest.mark.parametrize("name", ROOT_FOUND)
def test_crossing_root_finding_matches_dense_sampling(name, radius, rng):
    """Random segments: ending inside, passing through and out the far side, or missing."""
    case = CASES[name]()
    starts, ends = random_segments(case, rng, 120)
    hit, t, n = case.collider.crossing(starts, ends, radius)
    assert np.all(np.isfinite(n))
    counted = {"hit": 0, "through": 0, "miss": 0}
    wrong = []
    for i in range(len(starts)):
        ref_hit, ref_t, f_min = ref_first_contact(case.phi, starts[i], ends[i], radius)
        if abs(f_min) < 5e-3:
            continue  # grazing within the sampling resolution: either answer is defensible
        d = ends[i] - starts[i]
        if ref_hit:
            slope = ref_gradient(case.phi, (starts[i] + ref_t * d)[None])[0] @ d
            if slope > -0.05 * np.linalg.norm(d):
                continue  # nearly tangent at the contact: t is ill-conditioned
        through = ref_hit and case.phi(ends[i][None])[0] > radius
        counted["miss" if not ref_hit else "through" if through else "hit"] += 1
        if hit[i] != ref_hit or abs(t[i] - ref_t) > T_TOL:
            wrong.append(f"segment {i} {starts[i].tolist()} -> {ends[i].tolist()}: got hit={hit[i]} t={t[i]:.6f}, "
                         f"reference hit={ref_hit} t={ref_t:.6f}{' (passes through, end clear)' if through else ''}")
            continue
        if ref_hit:
            xc = starts[i] + t[i] * d
            np.testing.assert_allclose(np.linalg.norm(n[i]), 1.0, atol=PHI_TOL)
            assert n[i] @ d < 0  # the normal opposes the approach
            if radius > 0:
                # the contact is a distance r off the surface, where phi is smooth
                np.testing.assert_allclose(n[i], ref_gradient(case.phi, xc[None])[0], atol=1e-5)
                assert case.phi(xc[None])[0] == pytest.approx(radius, abs=1e-4 * radius + 1e-7)
    assert counted["hit"] > 15 and counted["through"] > 10 and counted["miss"] > 10, counted
    assert not wrong, f"{len(wrong)} of {sum(counted.values())} segments disagree:\n" + "\n".join(wrong)


@pytest.mark.parametrize("name", SOLIDS)
@pytest.mark.parametrize("radius", [0.0, 0.05])
def test_crossing_starting_inside_and_missing(name, radius, rng):
    case = CASES[name]()
    # starts inside the shape or inside the radius band around it: t = 0
    x = case.points(rng)
    inside = x[case.phi(x) < radius - 1e-6][:40]
    ends = inside + rng.normal(size=inside.shape)
    hit, t, n = case.collider.crossing(inside, ends, radius)
    assert len(inside) >= 20
    assert hit.all()
    np.testing.assert_array_equal(t, 0.0)
    assert_unit_finite(n)
    # segments far from the shape: no hit, t = 1
    far = case.center + np.array([4.0, 0.0, 0.0]) * case.extent
    starts = far + rng.uniform(-0.5, 0.5, size=(20, 3)) * case.extent
    stops = starts + np.array([0.0, 1.0, 0.0]) * case.extent + rng.normal(size=(20, 3)) * 0.1
    hit, t, _ = case.collider.crossing(starts, stops, radius)
    assert not hit.any()
    np.testing.assert_array_equal(t, 1.0)


@pytest.mark.parametrize("radius", [0.0, 0.002])
@pytest.mark.parametrize("rotated", [False, True])
@pytest.mark.parametrize("slant", [0.0, 1.0, 4.5], ids=["head_on", "45deg", "shallow_12deg"])
def test_thin_wall_is_not_tunnelled(slant, rotated, radius):
    """A fast segment from one side of a 1 cm wall to the other, both ends outside.
    Only continuous detection sees it (regression case `thin_wall`)."""
    half = np.array([0.005, 1.0, 1.0])
    rot = tc.rotation_matrix((0.3, 0.2, 1.0), 0.9) if rotated else np.eye(3)
    center = np.array([0.2, -0.1, 0.3])
    wall = tc.Box(center=center, half_extents=half, rotation=rot)
    # local path: x from -0.2 to 0.2, y rising by 0.4 * slant, through the middle of the wall
    local0 = np.array([-0.2, -0.2 * slant, 0.1])
    local1 = np.array([0.2, 0.2 * slant, -0.1])
    x0, x1 = center + rot @ local0, center + rot @ local1
    assert ref_box(np.array([x0, x1]), center, half, rot).min() > radius  # both ends clear
    hit, t, n = wall.crossing(x0[None], x1[None], radius)
    ref_t = (-(half[0] + radius) - local0[0]) / (local1[0] - local0[0])  # the face x = -(h + r)
    assert hit[0]
    assert t[0] == pytest.approx(ref_t, abs=T_TOL)
    np.testing.assert_allclose(n[0], rot @ np.array([-1.0, 0.0, 0.0]), atol=1e-6)


@pytest.mark.parametrize("radius", [0.02, 0.05])
def test_box_edge_touches_at_radius_offset(radius):
    """A path passing the edge (0.5, 0.5, z) of a cube at distance 0.9 r hits, at 1.1 r misses."""
    box = tc.Box(half_extents=(0.5, 0.5, 0.5))
    edge = np.array([0.5, 0.5, 0.2])
    out = unit([1.0, 1.0, 0.0])
    along = unit([1.0, -1.0, 0.0])
    for gap, expect in ((0.9 * radius, True), (1.1 * radius, False)):
        mid = edge + gap * out
        x0, x1 = mid - along, mid + along
        hit, t, _ = box.crossing(x0[None], x1[None], radius)
        assert hit[0] == expect
        if expect:
            xc = x0 + t[0] * (x1 - x0)
            assert ref_box(xc[None], np.zeros(3), np.full(3, 0.5), np.eye(3))[0] == pytest.approx(radius, abs=1e-5)
            ref_hit, ref_t, _ = ref_first_contact(
                lambda x: ref_box(x, np.zeros(3), np.full(3, 0.5), np.eye(3)), x0, x1, radius)
            assert ref_hit and t[0] == pytest.approx(ref_t, abs=T_TOL)
        else:
            assert t[0] == 1.0
