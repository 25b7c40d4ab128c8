"""A NumPy re-implementation of tai_coll's default impulse scheme, for benchmarks and tests.

docs/physics.md 3, Implementation 3 ("elastic_contact", the default of `tai_coll.ImpulseSolver`)
for static plane, sphere and box colliders, vectorised over particles with one index set
per pass. It follows tai_coll/solvers/impulse.py and detection.py rule for rule:

1. candidate by symplectic Euler: v1 = v + dt g, x1 = x + dt v1;
2. last resort: for each collider the particle was already inside at time t beyond the
   slop (phi(x) < r - slop): the inelastic law on v1 (e = 0, friction as usual) and
   x1 = x + dt v1 + min(push_fraction depth, max_push_speed dt) n, collider after collider;
3. elastic passes (`elastic_iterations`, default 1): detect with v(t); the law with the
   collider's restitution on v(t), its change added to the candidate (x1 += dt dv);
4. contact passes (up to `max_iterations`): detect with the candidate velocity v1; the law
   with e = 0 on v1; the particle follows its path to the contact (fraction t of the
   substep) and the new velocity after it, x1 = x + t (x1 - x) + (1 - t) dt v_new; a particle
   still in contact after the cap gets the failsafe (v1 = 0, x1 = x, the colliders being
   still).

Detection (detection.py `detect`, first contact along the segment), collider after collider
in table order: a collider is a candidate when x1 interferes (phi(x1) < r) deeper than x
was, x not deeper than the slop, or when both ends are clear and the segment x -> x1
reaches the surface. Its contact lies where the segment first touches it: t = 0 with the
normal at x for x inside the slop band, else the crossing (closed form for planes and
spheres, conservative advancement for boxes). Among the candidates the tested velocity
approaches (v.n < -1e-6 |v| - 1e-12 m/s), the earliest contact wins; ties go to the
deeper x1.

Vectorisation and the savings NumPy can afford that the Taichi kernel does not take:
- positions and velocities are stored as (3, N) rows (structure of arrays), so each vector
  component is one contiguous array;
- each pass works on the index set that is still in play (all particles for the first
  elastic pass and the first contact pass, then only those that were processed);
- phi at x1 is computed once for every particle per substep and reused: by the first
  contact pass for particles the elastic pass left alone, and (reuse_geometry=True) as phi
  at x for the next substep; normals and crossings only for the few candidates.

Results agree with tai_coll bit for bit in most steps (f64 and f32). The one known source
of difference is the rotation of points into a box's frame: Taichi's 3x3 matrix-vector
product and NumPy's (BLAS) round differently in the last bit. Such a difference stays at
round-off for most particles; on a particle sliding over a curved surface (the normal
depends on the position) it grows from step to step, and once it tips a threshold (the
approach test, the slop band, a grazing crossing) the two runs follow different valid
trajectories.

Unsupported (ValueError): moving colliders, cylinders and capsules, other schemes, a
domain box. A non-finite state raises FloatingPointError instead of freezing particles.
"""

from __future__ import annotations

import numpy as np

# tai_coll.geometry.kinds
PLANE = 0
SPHERE = 1
BOX = 2
KIND_NAMES = {PLANE: "plane", SPHERE: "sphere", BOX: "box"}

# tai_coll.geometry.analytic / marching, solvers.detection constants
TINY = 1e-12
APPROACH_EPS = 1e-6
APPROACH_FLOOR = 1e-12
ADVANCE_ITERATIONS = 48
SEARCH_ITERATIONS = 48
BISECT_ITERATIONS = 40
ADVANCE, SEARCH, BISECT = 0, 1, 2
TOUCH_REL = 1e-4
TOUCH_ABS = 1e-7

WET_LAWS = ("linear", "exponential")


# ----------------------------------------------------------------------------- vector rows
def _dot(a, b):
    """Row-wise a.b for (3, k) arrays, summed x + y + z as Taichi's Vector.dot does."""
    out = a[0] * b[0]
    out += a[1] * b[1]
    out += a[2] * b[2]
    return out


def _norm(a):
    return np.sqrt(_dot(a, a))


def _at(value, index):
    """value[index] for per-particle arrays; scalars pass through."""
    return value if np.ndim(value) == 0 else value[index]


# ----------------------------------------------------------------------------- colliders
class StaticCollider:
    """A still collider: kind, parameters and pose as tai_coll stores them, and its material."""

    def __init__(self, kind: int, params, center, rotation, *, restitution=0.5, friction=0.3,
                 wet_friction=0.0, dtype=np.float64):
        if kind not in KIND_NAMES:
            raise ValueError(f"kind must be one of {KIND_NAMES} (plane, sphere, box); got {kind!r}")
        self.kind = int(kind)
        self.dtype = np.dtype(dtype)
        f = self.dtype.type
        self.params = np.zeros(4, self.dtype)
        p = np.asarray(params, dtype=np.float64).ravel()
        self.params[: min(len(p), 4)] = p[:4]
        self.center = np.asarray(center, dtype=self.dtype).reshape(3, 1)
        R = np.asarray(rotation, dtype=self.dtype).reshape(3, 3)
        self.identity = bool(np.array_equal(R, np.eye(3)))
        self.R = np.ascontiguousarray(R)
        self.Rt = np.ascontiguousarray(R.T)
        self.radius = f(self.params[0])
        self.half = self.params[:3].reshape(3, 1).copy()
        self.plane_normal = np.ascontiguousarray(R[:, 1]).reshape(3, 1)  # R @ (0, 1, 0)
        self.restitution = f(restitution)
        self.friction = f(friction)
        self.wet_friction = f(wet_friction)

    @classmethod
    def from_shape(cls, shape, material=None, *, center=None, rotation=None, dtype=np.float64):
        """From a tai_coll collider (Plane, Sphere, Box) and tai_coll Material (default one
        if None), at the shape's rest pose unless center/rotation are given."""
        from tai_coll.geometry import kinds

        assert (kinds.PLANE, kinds.SPHERE, kinds.BOX) == (PLANE, SPHERE, BOX)
        if shape.kind not in KIND_NAMES:
            raise ValueError(f"collider kind {shape.kind_name!r} is not supported")
        if material is None:
            from tai_coll import Material

            material = Material()
        return cls(shape.kind, shape.params, shape.center if center is None else center,
                   shape.rotation if rotation is None else rotation, restitution=material.restitution,
                   friction=material.friction, wet_friction=material.wet_friction, dtype=dtype)

    @property
    def kind_name(self) -> str:
        return KIND_NAMES[self.kind]

    # -- local frame: p = R^T (x - c)
    def _local(self, X):
        P = X - self.center
        if not self.identity:
            P = self.Rt @ P
        return P

    def _world(self, n_local):
        return n_local if self.identity else self.R @ n_local

    def signed_distance(self, X):
        """phi at world points X (3, k). Same values as sdf.py; the box's two branches are
        folded into |max(q, 0)| + min(max(q), 0), exact since one of the terms is 0."""
        if self.kind == PLANE:
            if self.identity:
                return X[1] - self.center[1, 0]
            P = X - self.center
            out = self.Rt[1, 0] * P[0]
            out += self.Rt[1, 1] * P[1]
            out += self.Rt[1, 2] * P[2]
            return out
        P = self._local(X)
        if self.kind == SPHERE:
            phi = _norm(P)
            phi -= self.radius
            return phi
        # box: q = |p| - half
        np.abs(P, out=P)
        P -= self.half
        q_max = np.maximum(P[0], P[1])
        np.maximum(q_max, P[2], out=q_max)
        np.maximum(P, 0.0, out=P)
        phi = _norm(P)
        np.minimum(q_max, 0.0, out=q_max)
        phi += q_max
        return phi

    def signed_distance_normal(self, X):
        """(phi, outward unit normal (3, k)) at world points X (3, k), as sdf.py computes them."""
        k = X.shape[1]
        if self.kind == PLANE:
            return self.signed_distance(X), np.repeat(self.plane_normal, k, axis=1)
        P = self._local(X)
        if self.kind == SPHERE:
            length = _norm(P)
            with np.errstate(divide="ignore", invalid="ignore"):
                n = P / length
            small = ~(length > TINY)
            if small.any():
                n[:, small] = np.array([[0.0], [1.0], [0.0]], dtype=self.dtype)
            return length - self.radius, self._world(n)
        phi, n = _box_local(P, self.half, self.dtype)
        return phi, self._world(n)

    def carried(self, X):
        """detection.py `carried` at elapsed = 0 for a still collider: x itself (no transform)."""
        return X

    # -- trajectory crossing (crossing.py), world segments X0 -> X1 of spheres of radius r
    def crossing(self, X0, X1, r):
        """(hit (k,), t (k,), world normal (3, k)) for a sphere of radius r moving X0 -> X1."""
        P0 = self._local(X0)
        P1 = self._local(X1)
        if self.kind == PLANE:
            hit, t, n = _plane_crossing(P0, P1, r, self.dtype)
        elif self.kind == SPHERE:
            hit, t, n = _sphere_crossing(P0, P1, self.radius, r, self.dtype)
        else:
            hit, t, n = _advance_crossing(self, P0, P1, r)
        return hit, t, self._world(n)


def _box_local(P, half, dtype):
    """sdf.py `box_sdf` at local points P (3, k): (phi, local normal (3, k))."""
    sign = np.where(P >= 0.0, dtype.type(1.0), dtype.type(-1.0))  # sign_nonzero
    q = np.abs(P)
    q -= half
    outside = np.maximum(q, 0.0)
    out_len = _norm(outside)
    is_out = out_len > 0.0
    q_max = np.maximum(np.maximum(q[0], q[1]), q[2])
    phi = np.where(is_out, out_len, q_max)
    # Outside: sign * max(q, 0) / |max(q, 0)|. Inside (or on a face): the face of the largest q.
    n = outside / np.where(is_out, out_len, dtype.type(1.0))
    inside = ~is_out
    fx = (q[0] >= q[1]) & (q[0] >= q[2])
    fy = ~fx & (q[1] >= q[2])
    fz = ~(fx | fy)
    n[0] += fx & inside
    n[1] += fy & inside
    n[2] += fz & inside
    n *= sign
    return phi, n


def _plane_crossing(P0, P1, r, dtype):
    d0 = P0[1] - r
    d1 = P1[1] - r
    k = P0.shape[1]
    hit = d0 < 0.0
    t = np.where(hit, dtype.type(0.0), dtype.type(1.0))
    late = ~hit & (d1 < 0.0)
    if late.any():
        d0l = _at(d0, late)
        t[late] = d0l / (d0l - _at(d1, late))
    hit |= late
    n = np.zeros((3, k), dtype)
    n[1] = 1.0
    return hit, t, n


def _sphere_crossing(P0, P1, radius, r, dtype):
    # |p0 + t d|^2 = (R + r)^2  ->  a t^2 + 2 b t + c = 0, first root in [0, 1]
    R = radius + r
    d = P1 - P0
    a = _dot(d, d)
    b = _dot(P0, d)
    c = _dot(P0, P0) - R * R
    hit = c < 0.0
    t = np.where(hit, dtype.type(0.0), dtype.type(1.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        disc = b * b - a * c
        root = c / (-b + np.sqrt(disc))
    late = ~hit & (a > 0.0) & (b < 0.0) & (disc >= 0.0) & (root <= 1.0)
    t[late] = root[late]
    hit |= late
    p = P0 + t * d
    length = _norm(p)
    with np.errstate(divide="ignore", invalid="ignore"):
        n = p / length
    small = ~(length > 1e-12)
    if small.any():
        n[:, small] = np.array([[0.0], [1.0], [0.0]], dtype=dtype)
    return hit, t, n


def _advance_crossing(col, P0, P1, r):
    """crossing.py `advance_crossing` for all segments in lock step: conservative
    advancement; a minimum search on the slope's sign when advancing runs out of patience
    (grazing paths); root bisection once a point inside is found. A segment leaves the loop
    where the Taichi loop breaks."""
    dtype = col.dtype
    f = dtype.type
    k = P0.shape[1]
    d = P1 - P0
    length = _norm(d)
    tol = np.broadcast_to(np.maximum(f(TOUCH_REL) * r, f(TOUCH_ABS)), (k,))
    rr = np.broadcast_to(r, (k,))
    hit = np.zeros(k, bool)
    t = np.ones(k, dtype)
    n = np.zeros((3, k), dtype)
    n[1] = 1.0
    phase = np.full(k, ADVANCE, np.int8)
    lo = np.zeros(k, dtype)
    hi = np.ones(k, dtype)
    s = np.zeros(k, dtype)
    live = np.arange(k)
    eps = f(1e-12)
    for it in range(ADVANCE_ITERATIONS + SEARCH_ITERATIONS + BISECT_ITERATIONS):
        if live.size == 0:
            break
        sl = s[live]
        gap, n_s = _box_local(P0[:, live] + sl * d[:, live], col.half, dtype)
        gap -= rr[live]
        slope = _dot(n_s, d[:, live])
        ph = phase[live]
        leave = np.zeros(live.size, bool)
        bis = ph == BISECT
        inside = ~bis & (gap < 0.0)
        touch = ~bis & ~inside & (gap <= tol[live])
        rest = ~bis & ~inside & ~touch
        away = rest & ((slope >= 0.0) | (length[live] == 0.0))
        adv = rest & ~away & (ph == ADVANCE)
        search_right = rest & ~away & (ph == SEARCH)
        # root bisection
        if bis.any():
            j, sb, gb = live[bis], sl[bis], gap[bis]
            n[:, j] = n_s[:, bis]
            neg = gb < 0.0
            hi[j[neg]] = sb[neg]
            lo[j[~neg]] = sb[~neg]
            narrow = hi[j] - lo[j] <= eps
            leave[np.flatnonzero(bis)[narrow]] = True
            jm = j[~narrow]
            s[jm] = 0.5 * (lo[jm] + hi[jm])
        # a point inside: at the start a contact, else bracket the root
        if inside.any():
            at0 = inside & (sl == 0.0)
            j = live[at0]
            hit[j], t[j], n[:, j] = True, 0.0, n_s[:, at0]
            leave |= at0
            into = inside & ~at0
            j = live[into]
            phase[j] = BISECT
            hi[j] = sl[into]
            s[j] = 0.5 * (lo[j] + hi[j])
        # close enough: a contact
        if touch.any():
            j = live[touch]
            hit[j], t[j], n[:, j] = True, sl[touch], n_s[:, touch]
            leave |= touch
        # clear and moving away: a miss while advancing; the minimum lies left while searching
        if away.any():
            leave |= away & (ph == ADVANCE)
            sm = away & (ph == SEARCH)
            j = live[sm]
            hi[j] = sl[sm]
            narrow = hi[j] - lo[j] <= eps
            leave[np.flatnonzero(sm)[narrow]] = True
            jm = j[~narrow]
            s[jm] = 0.5 * (lo[jm] + hi[jm])
        # advance by the gap, which never steps over the surface
        if adv.any():
            j = live[adv]
            sa = sl[adv]
            lo[j] = sa
            s_next = sa + gap[adv] / length[j]
            beyond = s_next >= 1.0  # the rest of the segment lies inside a clear ball
            leave[np.flatnonzero(adv)[beyond]] = True
            jm = j[~beyond]
            s[jm] = s_next[~beyond]
            if it >= ADVANCE_ITERATIONS - 1 and jm.size:
                phase[jm] = SEARCH  # grazing: find the minimum of phi on [s, 1]
                hi[jm] = 1.0
                lo[jm] = s[jm]
                s[jm] = 0.5 * (lo[jm] + hi[jm])
        # searching: the minimum lies to the right
        if search_right.any():
            j = live[search_right]
            lo[j] = sl[search_right]
            narrow = hi[j] - lo[j] <= eps
            leave[np.flatnonzero(search_right)[narrow]] = True
            jm = j[~narrow]
            s[jm] = 0.5 * (lo[jm] + hi[jm])
        live = live[~leave]
    bis = phase == BISECT
    hit[bis] = True
    t[bis] = hi[bis]
    return hit, t, n


# ----------------------------------------------------------------------------- response
def respond(v, n, restitution, friction, wet_friction, wet_law="linear"):
    """docs/physics.md 2 (laws.py `respond`) on rows (3, k) of relative velocity v and normal n."""
    vn = _dot(v, n)
    vt = v - vn * n
    dvn = -vn if np.ndim(restitution) == 0 and restitution == 0.0 else (1.0 + restitution) * (-vn)
    vt_len = _norm(vt)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.maximum(1.0 - friction * dvn / vt_len, 0.0)
    scale = np.where(vt_len > 0.0, scale, 0.0)
    if np.any(wet_friction != 0.0):
        if wet_law == "linear":
            scale *= np.maximum(1.0 - wet_friction * dvn, 0.0)
        else:
            scale *= np.exp(-wet_friction * dvn)
    out = scale * vt
    if np.any(restitution != 0.0):
        out -= (restitution * vn) * n
    return np.where(vn < 0.0, out, v)


def approaching(v, n):
    """(v - vs).n < -eps (|v| + |vs|) - floor with a still surface, vs = 0 (detection.py)."""
    return _dot(v, n) < -APPROACH_EPS * _norm(v) - APPROACH_FLOOR


# ----------------------------------------------------------------------------- the solver
class NumpyImpulseReference:
    """Particles against static colliders, stepped with tai_coll's default impulse scheme.

    colliders: StaticCollider list, in tai_coll's table order (order decides ties).
    positions, velocities: (N, 3) in m, m/s. radius: m, scalar or (N,).
    gravity (m/s^2), dt (s), substeps (per `step` frame) and the solver options as in
    `tai_coll.ImpulseSolver`. dtype: np.float32 (Taichi's default precision) or np.float64.
    reuse_geometry: keep phi at the resolved positions for the next substep (saves one
    signed-distance evaluation per collider and particle and substep; same results).
    """

    def __init__(self, *, colliders, positions, velocities=None, radius=0.005, gravity=(0.0, -9.81, 0.0),
                 dt=1.0 / 600.0, substeps=10, max_iterations=8, elastic_iterations=1, push_fraction=0.1,
                 max_push_speed=1.0, slop=1e-3, wet_law="linear", dtype=np.float64,
                 reuse_geometry=True):
        self.dtype = np.dtype(dtype)
        if self.dtype not in (np.dtype(np.float32), np.dtype(np.float64)):
            raise ValueError(f"dtype must be float32 or float64; got {self.dtype}")
        if wet_law not in WET_LAWS:
            raise ValueError(f"wet_law must be one of {WET_LAWS}; got {wet_law!r}")
        if int(max_iterations) < 1 or int(elastic_iterations) < 0 or int(substeps) < 1:
            raise ValueError("max_iterations >= 1, elastic_iterations >= 0 and substeps >= 1 are required")
        f = self.dtype.type
        self.colliders = [c if c.dtype == self.dtype else _recast(c, self.dtype) for c in colliders]
        x = np.asarray(positions, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 3:
            raise ValueError(f"positions must have shape (N, 3); got {x.shape}")
        self._x = np.ascontiguousarray(x.T, dtype=self.dtype)
        self._v = (np.zeros_like(self._x) if velocities is None
                   else np.ascontiguousarray(np.asarray(velocities, dtype=np.float64).T, dtype=self.dtype))
        if self._v.shape != self._x.shape:
            raise ValueError("velocities must have the shape of positions")
        r = np.asarray(radius, dtype=self.dtype)
        if r.ndim == 1 and r.size and np.all(r == r[0]):
            r = r[0]
        self._r = f(r) if r.ndim == 0 else r
        self._slop = f(slop) * self._r
        self._r_minus_slop = self._r - self._slop
        self.gravity = np.asarray(gravity, dtype=np.float64)
        self.dt = float(dt)
        self._dt = f(dt)
        self._g_dt = (self._dt * self.gravity.astype(self.dtype)).reshape(3, 1)
        self.substeps = int(substeps)
        self.max_iterations = int(max_iterations)
        self.elastic_iterations = int(elastic_iterations)
        self._push_fraction = f(push_fraction)
        self._push_limit = f(max_push_speed) * self._dt
        self.wet_law = wet_law
        self.reuse_geometry = bool(reuse_geometry)
        self._phi = None  # phi of each collider at the current positions, when known
        mats = np.array([(c.restitution, c.friction, c.wet_friction) for c in self.colliders], dtype=self.dtype)
        self._uniform_material = bool(len(mats) == 0 or np.all(mats == mats[0]))
        self._materials = mats
        self.stats = {"failsafe": 0, "repulsion": 0}
        self.last_failsafe = np.empty(0, np.intp)  # particles the failsafe stopped in the last substep
        self.substep_count = 0

    @classmethod
    def from_scene(cls, scene, *, dtype=None, **options):
        """A reference with the colliders, particles and solver options of a tai_coll Scene
        (static plane, sphere and box colliders, the elastic_contact scheme, no domain)."""
        from tai_coll import runtime

        if dtype is None:
            dtype = runtime.float_dtype()
        if scene.domain is not None:
            raise ValueError("scenes with a domain box are not supported")
        for e in scene.colliders:
            if e.is_kinematic:
                raise ValueError("moving colliders are not supported")
        if np.any(scene.particle_status() != "active"):
            raise ValueError("every particle must be active")
        colliders = [StaticCollider.from_shape(e.shape, e.material, center=e.center, rotation=e.rotation,
                                               dtype=dtype) for e in scene.colliders]
        kwargs = dict(colliders=colliders, positions=scene.positions(), velocities=scene.velocities(),
                      radius=scene.radii(), gravity=scene.gravity, dt=scene.dt, substeps=scene.substeps,
                      dtype=dtype, **solver_options(scene.solver))
        kwargs.update(options)
        return cls(**kwargs)

    # ---------------------------------------------------------------- reading
    @property
    def num_particles(self) -> int:
        return self._x.shape[1]

    def positions(self) -> np.ndarray:
        return self._x.T.copy()

    def velocities(self) -> np.ndarray:
        return self._v.T.copy()

    def nbytes(self) -> int:
        """Bytes held between steps: state, radii and the cached signed distances."""
        total = self._x.nbytes + self._v.nbytes + np.asarray(self._r).nbytes
        if self._phi is not None:
            total += sum(p.nbytes for p in self._phi)
        return total

    # ---------------------------------------------------------------- stepping
    def step(self, frames: int = 1) -> None:
        for _ in range(frames):
            for _ in range(self.substeps):
                self.substep()

    def substep(self) -> None:
        dt = self._dt
        self.last_failsafe = np.empty(0, np.intp)
        x0, v0 = self._x, self._v
        # integrate without collisions (docs/physics.md 3): v1 = v + dt g, x1 = x + dt v1
        v1 = v0 + self._g_dt
        x1 = dt * v1
        x1 += x0
        phi0 = self._phi if self._phi is not None else [c.signed_distance(x0) for c in self.colliders]
        self._repel_start_penetrations(x0, x1, v1, phi0)

        # phi at the candidate, and the segment lengths, for every particle
        phi1 = [c.signed_distance(x1) for c in self.colliders]
        d = x1 - x0
        length = _norm(d)
        del d

        def refresh(S):
            """Recompute phi(x1) and |x1 - x0| of the particles S after x1 changed."""
            x1s = x1[:, S]
            for c, col in enumerate(self.colliders):
                phi1[c][S] = col.signed_distance(x1s)
            length[S] = _norm(x1s - x0[:, S])

        def view(S):
            if S is None:
                return x0, x1, phi0, phi1, length, self._r, self._slop
            return (x0[:, S], x1[:, S], [p[S] for p in phi0], [p[S] for p in phi1], length[S],
                    _at(self._r, S), _at(self._slop, S))

        # docs/physics.md 3, Implementation 3: the elastic law on v(t), its change added to the candidate
        S = None
        v_start = v0
        for _ in range(self.elastic_iterations):
            found, normal, _, _ = self._detect(*view(S), v_start)
            hit = np.flatnonzero(found >= 0)
            if hit.size == 0:
                break
            C = hit if S is None else S[hit]
            vh = v_start[:, hit]
            v_new = self._law(vh, normal[:, hit], found[hit], elastic=True)
            dv = v_new - vh
            v1[:, C] += dv
            x1[:, C] += dt * dv
            S, v_start = C, v_new
            refresh(S)

        # contact passes: e = 0 on v1, on to the contact and the new velocity after it; then the failsafe
        S = None
        for contact_pass in range(self.max_iterations + 1):
            found, normal, when, at = self._detect(*view(S), v1 if S is None else v1[:, S])
            hit = np.flatnonzero(found >= 0)
            if hit.size == 0:
                break
            C = hit if S is None else S[hit]
            if contact_pass == self.max_iterations:
                # failsafe (docs/physics.md 3): stop relative to the (still) collider
                v1[:, C] = 0.0
                x1[:, C] = x0[:, C]
                for c in range(len(self.colliders)):
                    phi1[c][C] = phi0[c][C]
                self.stats["failsafe"] += int(C.size)
                self.last_failsafe = C
                break
            v_new = self._law(v1[:, C], normal[:, hit], found[hit], elastic=False)
            v1[:, C] = v_new
            # along the path up to the contact (fraction `when`), the new velocity after it
            x1[:, C] = at[:, hit] + (1.0 - when[hit]) * (dt * v_new)
            S = C
            refresh(S)

        if not (np.isfinite(x1.sum()) and np.isfinite(v1.sum())):
            bad = np.flatnonzero(~(np.isfinite(x1).all(axis=0) & np.isfinite(v1).all(axis=0)))
            if bad.size:
                raise FloatingPointError(f"{bad.size} particle(s) turned non-finite, e.g. {bad[:10].tolist()}")
        self._x, self._v = x1, v1
        self._phi = phi1 if self.reuse_geometry else None
        self.substep_count += 1

    def _repel_start_penetrations(self, x0, x1, v1, phi0):
        """Last resort (docs/physics.md 3, impulse.py): a particle already inside a collider at
        time t beyond the slop keeps the penetration for this substep; its velocity gets the
        inelastic law (e = 0, friction as usual) and its position is pushed out along the
        normal by min(push_fraction depth, max_push_speed dt); collider after collider."""
        dt = self._dt
        for c, col in enumerate(self.colliders):
            ii = np.flatnonzero(phi0[c] < self._r_minus_slop)
            if ii.size == 0:
                continue
            self.stats["repulsion"] += int(ii.size)
            _, n = col.signed_distance_normal(x0[:, ii])
            depth = _at(self._r, ii) - phi0[c][ii]
            v_new = respond(v1[:, ii], n, self.dtype.type(0.0), col.friction, col.wet_friction, self.wet_law)
            v1[:, ii] = v_new
            x_new = dt * v_new
            x_new += x0[:, ii]
            x_new += np.minimum(self._push_fraction * depth, self._push_limit) * n
            x1[:, ii] = x_new

    def _detect(self, x0, x1, phi0, phi1, length, r, slop, v):
        """detection.py `detect` for k particles: rows x0, x1 (3, k), phi of each collider at
        x0 and x1, |x1 - x0|, radii and slops; v the velocity tested for approach, or None
        for the average velocity (x1 - x0)/dt (computed only where needed).

        Candidates, collider after collider: x1 interferes and lies deeper than x0, with x0
        no deeper than the slop; or both ends clear and the segment reaches the surface.
        The contact is where the segment first touches (t = 0 and the normal at x0 for x0
        inside the slop band, else the crossing). Among approached candidates the earliest
        contact wins, ties going to the deeper x1.
        Returns (collider index or -1 (k,) int8, normal (3, k), valid where index >= 0)."""
        k = x0.shape[1]
        found = np.full(k, -1, np.int8)
        normal = np.empty((3, k), self.dtype)
        when = np.zeros(k, self.dtype)
        at = np.empty((3, k), self.dtype)
        best_t = None   # (k,), 2 until a contact is taken
        best_gap = None  # (k,), 0 until a contact is taken

        for c, col in enumerate(self.colliders):
            gap1 = phi1[c] - r
            # interference, or a clear end the segment may still reach (phi is 1-Lipschitz)
            ii = np.flatnonzero(gap1 < length)
            if ii.size == 0:
                continue
            g1 = gap1[ii]
            g0 = phi0[c][ii] - _at(r, ii)
            cand = np.where(g1 < 0.0, (g0 >= -_at(slop, ii)) & (g1 < np.minimum(g0, 0.0)), g0 >= 0.0)
            ii, g1, g0 = ii[cand], g1[cand], g0[cand]
            if ii.size == 0:
                continue
            m = ii.size
            t = np.zeros(m, self.dtype)
            n = np.empty((3, m), self.dtype)
            hit = np.ones(m, bool)
            band = g0 < 0.0  # x0 inside the slop band: contact at x0, its normal
            if band.any():
                _, n[:, band] = col.signed_distance_normal(x0[:, ii[band]])
            clear = ~band
            if clear.any():
                # sweep from x0 carried with the collider (x0 itself, up to round-off)
                jc = ii[clear]
                start = col.carried(x0[:, jc])
                hit[clear], t[clear], n[:, clear] = col.crossing(start, x1[:, jc], _at(r, jc))
            if best_t is None:
                keep = hit
            else:
                bt = best_t[ii]
                keep = hit & ((t < bt) | ((t == bt) & (g1 < best_gap[ii])))
            sel = np.flatnonzero(keep)
            if sel.size == 0:
                continue
            j = ii[sel]
            vel = (x1[:, j] - x0[:, j]) / self._dt if v is None else v[:, j]
            ok = approaching(vel, n[:, sel])
            sel, j = sel[ok], j[ok]
            if j.size == 0:
                continue
            if best_t is None:
                best_t = np.full(k, 2.0, self.dtype)
                best_gap = np.zeros(k, self.dtype)
            best_t[j] = t[sel]
            best_gap[j] = g1[sel]
            found[j] = c
            normal[:, j] = n[:, sel]
            when[j] = t[sel]
            at[:, j] = x0[:, j] + t[sel] * (x1[:, j] - x0[:, j])
        return found, normal, when, at

    def _law(self, v, n, which, *, elastic):
        """The collision routine with the material of collider `which` (per particle);
        restitution only in the elastic passes (e = 0 in contact passes)."""
        if self._uniform_material:
            e, mu, wet = self._materials[0]
        else:
            e, mu, wet = (self._materials[which, j] for j in range(3))
        if not elastic:
            e = self.dtype.type(0.0)
        return respond(v, n, e, mu, wet, self.wet_law)


def solver_options(solver) -> dict:
    """The keyword arguments of NumpyImpulseReference matching a tai_coll ImpulseSolver."""
    if getattr(solver, "scheme", None) != "elastic_contact":
        raise ValueError(f"only the elastic_contact impulse scheme is implemented; got {solver!r}")
    if getattr(solver, "last_resort", None) is not None:
        raise ValueError("only the position push is implemented as the last resort; got a repulsion field")
    return dict(max_iterations=solver.max_iterations, elastic_iterations=solver.elastic_iterations,
                push_fraction=solver.push_fraction, max_push_speed=solver.max_push_speed,
                slop=solver.slop, wet_law=solver.wet_law)


def _recast(col: StaticCollider, dtype) -> StaticCollider:
    return StaticCollider(col.kind, col.params, col.center.ravel(), col.R, restitution=col.restitution,
                          friction=col.friction, wet_friction=col.wet_friction, dtype=dtype)
