"""Benchmark: tai_coll against NVIDIA Warp on the same machine, in one invocation, where
particles are in contact (issue 23). Warp (`warp-lang`) is a benchmark-only extra:
`pip install 'tai_coll[bench]'`; tai_coll never imports it.

    python tools/bench_warp.py                         # both rows: a 1M layer, a 100k bed (CPU)
    python tools/bench_warp.py --rows bed --bed-particles 20000 --warp-variants impulse
    python tools/bench_warp.py --arch cuda --layer-particles 1000000,10000000 --layer-frames 100 \
        --bed-particles 1000000,10000000 --pair-methods gauss-seidel,jacobi    # the GPU rows

Rows (r = 5 mm, dt = 1/600 s, e = 0.5, mu = 0.3, f32, particle-steps per second):
- layer: N particles at rest in a layer 0 to 2 cm above a floor plane, 10 substeps a frame.
  tai_coll: a Scene with the plane and the default ImpulseSolver. Warp: one kernel a step:
  gravity (symplectic Euler), the particle put back on the plane, the restitution law on the
  normal velocity and Coulomb friction on the tangential one (the same 1-D impulse law).
- bed: 100,000 particles on a jittered lattice 2.2 r apart, 6 layers deep, in a box (floor
  and four walls); 300 steps to settle, then 100 timed. tai_coll: enable_particle_collisions()
  (Gauss-Seidel impulses, the default; --pair-methods adds method="jacobi", and a count of
  passes: jacobi:2:10 is 2 contact and 10 projection passes). Warp: three solvers of the same
  bed, the script's own kernels (--warp-variants, default all). Each step of each: one
  `wp.HashGrid` build and one gather (a query per particle) into half lists (planes within the
  skin, particles j > i within 2 r + skin: every pair computed once, its result added to both
  particles), then passes over the lists; launches only, nothing read back inside the timed
  loop.
  - pbd: position-based Jacobi: predict; 4 passes, each moving a particle by 1.5 (SOR) times
    the mean of its pairs' corrections (half the overlap; positional Coulomb friction: the
    relative tangential move undone up to mu times the overlap), then out of the planes; the
    velocity from the move, with restitution e for approaches faster than 2 g dt.
  - impulse: impulse-based Jacobi: gravity; 4 iterations of accumulated normal impulses
    (restitution e above 2 g dt, speculative contacts within the skin) and Coulomb friction
    impulses, with mass splitting (a pair's change divided by both particles' list counts),
    warm-started from the step before's impulses; overlaps pushed apart in position in the
    first iteration (a Baumgarte bias velocity, kept by the warm start, made the bed boil);
    then x += v dt.
  - dem: linear spring-dashpot, k_n = 1000 N/m on 1.31 g particles (glass), dashpots for
    e = 0.5, tangential viscous friction capped by Coulomb, symplectic Euler. dt = 1/600 s is
    unstable for it (a pair's contact lasts 2.5 ms), so 5 substeps of 333 us a step (about 8
    a contact; 0.15 of the critical 2 sqrt(m / k)), over a list gathered once a step with a
    skin of 0.3 r. The stiffness keeps the mean overlap near tai_coll's (about 0.5 % of r); a
    particle-step is one of dt = 1/600 s, as for the others. (Without tangential springs a
    loaded contact creeps: 7 mm/s on a slope of tan 0.2 < mu.)
  Every solver reports the mean overlap of touching pairs (relative to the radius, by a
  tai_coll scene's measure), the touching pairs a particle (how far its bed has packed: the
  work each pair pass has) and the largest speed after the timed steps, and the process's CPU
  time a particle-step. tai_coll's ratio is given against each, and against Warp's fastest
  (the overlaps beside the rates).
  The first Warp solver here (PBD, 5.0e5 particle-steps/s) queried the hash grid in every
  Jacobi pass: 4 queries a step of 27 cells of 2 r, about 400 ns a particle each, 97 % of its
  time; and it cleared a 128^3 grid (16 MB) every build.
Warp's CPU backend runs one thread; tai_coll runs --threads (default 2). On a GPU each side's
timed steps end with a synchronize (Taichi's ti.sync, Warp's synchronize_device). tai_coll's
rows also give the bytes a particle of every array its scene holds (Scene.state_nbytes), and the
largest scene of the row that fits in --memory-gb (default 80, a GPU's): by those bytes, or by
the count Taichi's 32-bit array offsets allow (the particle arrays' for the layer, the
neighbour lists' for the bed; tai_coll refuses more), whichever is smaller.
Prints a table with the ratios and writes bench_results/bench_warp.json (every solver's
figures and settings), rewritten as each row is finished. With --repeats N every row runs N
times, tai_coll and Warp alternately, and reports its run of median ratio with the range:
on a shared 2-core machine the ratio moves from hour to hour (tai_coll runs two threads,
Warp one; docs/design-notes.md, "Against Warp").
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import taichi as ti

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import tai_coll as tc  # noqa: E402
from tai_coll.neighbors import hash_grid  # noqa: E402
from tai_coll.scene import particles  # noqa: E402
from tools.bench import count, machine_info, report_path, write_json  # noqa: E402

R = 0.005
DT = 1.0 / 600.0
E = 0.5
MU = 0.3
G = -9.81
SUBSTEPS = 10


# ---------------------------------------------------------------------- the scenes
def layer_positions(n: int, seed: int = 0) -> np.ndarray:
    """n particles at random in a layer from R to R + 2 cm above y = 0, over a square of side
    sqrt(n) diameters (the area grows with n; the layer stays as dense)."""
    rng = np.random.default_rng(seed)
    side = np.sqrt(n) * 2.0 * R
    return np.column_stack([rng.uniform(0, side, n), R + rng.uniform(0.0, 0.02, n), rng.uniform(0, side, n)])


def bed_positions(n: int, layers: int = 6, seed: int = 0) -> tuple:
    """A jittered lattice 2.2 r apart, `layers` deep; returns (positions, box width)."""
    rng = np.random.default_rng(seed)
    per_layer = int(np.ceil(n / layers))
    side = int(np.ceil(np.sqrt(per_layer)))
    spacing = 2.2 * R
    i, k, j = np.meshgrid(np.arange(side), np.arange(side), np.arange(layers), indexing="ij")
    x = np.column_stack([i.ravel(), j.ravel(), k.ravel()]).astype(np.float64)[:n] * spacing + spacing / 2
    x += rng.uniform(-0.1, 0.1, x.shape) * R
    return x, side * spacing


def tai_coll_layer(n: int, frames: int) -> dict:
    scene = tc.Scene(dt=DT, substeps=SUBSTEPS)
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=E, friction=MU))
    scene.add_particles(positions=layer_positions(n), radius=R)
    scene.step(2)  # (compiles)
    ti.sync()
    t0 = time.perf_counter()
    scene.step(frames)
    ti.sync()  # (a GPU's launches return before they finish)
    seconds = time.perf_counter() - t0
    y = scene.positions()[:, 1]
    return {"rate": n * SUBSTEPS * frames / seconds, "seconds": seconds, "lowest": float(y.min()),
            "state_bytes_per_particle": scene.state_nbytes() / n}


def largest_scene(bytes_per_particle: float, memory_gb: float, pairs: bool) -> dict:
    """The most particles of a row's scene that `memory_gb` (10^9 B) holds at the row's bytes a
    particle, and what limits it: "memory", or Taichi's 32-bit array offsets, which tai_coll
    enforces: particles.MAX_STORED for any scene, hash_grid.MAX_LISTED with particle
    collisions (pairs)."""
    by_memory = int(memory_gb * 1e9 // bytes_per_particle)
    indexed, arrays = ((hash_grid.MAX_LISTED, "the neighbour lists") if pairs
                       else (particles.MAX_STORED, "the particle arrays"))
    if indexed < by_memory:
        return {"particles": indexed, "limit": f"32-bit offsets of {arrays}", "by_memory": by_memory,
                "memory_gb": memory_gb}
    return {"particles": by_memory, "limit": "memory", "by_memory": by_memory, "memory_gb": memory_gb}


def pair_options(spec: str) -> dict:
    """enable_particle_collisions options from a --pair-methods entry: "gauss-seidel",
    "jacobi", or either with its contact and projection passes, "jacobi:2:10"."""
    method, *passes = spec.split(":")
    if method not in ("gauss-seidel", "jacobi") or len(passes) not in (0, 2) or \
            not all(p.isdigit() and int(p) > 0 for p in passes):
        raise ValueError(f"a pair method is gauss-seidel or jacobi, optionally :contact:projection passes "
                         f"(jacobi:2:10); got {spec!r}")
    return {"method": method, **({"iterations": int(passes[0]), "projection_iterations": int(passes[1])}
                                 if passes else {})}


def tai_coll_bed(n: int, settle: int, timed: int, method: str = "gauss-seidel") -> dict:
    x, width = bed_positions(n)
    scene = tc.Scene(dt=DT, substeps=SUBSTEPS)
    wall = tc.Material(restitution=E, friction=MU)
    for point, normal in (((0, 0, 0), (0, 1, 0)), ((0, 0, 0), (1, 0, 0)), ((width, 0, 0), (-1, 0, 0)),
                          ((0, 0, 0), (0, 0, 1)), ((0, 0, width), (0, 0, -1))):
        scene.add_collider(tc.Plane(point=point, normal=normal), material=wall)
    scene.add_particles(positions=x, radius=R)
    scene.enable_particle_collisions(material=tc.Material(restitution=E, friction=MU), **pair_options(method))
    scene.step(settle // SUBSTEPS)
    ti.sync()
    t0, c0 = time.perf_counter(), time.process_time()
    scene.step(timed // SUBSTEPS)
    ti.sync()
    seconds = time.perf_counter() - t0
    cpu = time.process_time() - c0
    return {"rate": n * timed / seconds, "seconds": seconds, "cpu_seconds": cpu, **work(cpu, n, timed),
            **contacts(scene.particle_overlap(), n), **speeds(scene.velocities()),
            "state_bytes_per_particle": scene.state_nbytes() / n}


# ---------------------------------------------------------------------- Warp
WARP_VARIANTS = ("pbd", "impulse", "dem")
GRAVITY = (0.0, G, 0.0)
REST_SPEED = 2.0 * abs(G) * DT  # pbd, impulse: slower approaches than this do not bounce
# The solvers' settings (see the module docstring).
PBD = {"passes": 4, "omega": 1.5, "skin": 0.2 * R}
IMPULSE = {"iterations": 4, "push": 1.0, "warm": 1.0, "skin": 0.2 * R}
DEM_DENSITY = 2500.0  # kg/m^3 (glass): a particle's mass is 1.31 g
DEM = {"substeps": 5, "stiffness": 1000.0, "skin": 0.3 * R}  # stiffness: k_n in N/m
CAPACITY = 16  # list slots a particle: planes within the skin and particles j > i within reach


def warp_kernels(wp):
    """The Warp side's kernels, written for this comparison: the layer's one-kernel step, and the
    bed's three solvers over one neighbour gather a step (returned as a dict by name).

    The bed's lists are half lists: particle i's row holds the planes within the skin (as
    -1 - plane) and the particles j > i within reach, so every pair is computed once, and its
    result is added to both particles (wp.atomic_add: a plain add on the one-thread CPU
    backend); a second kernel then applies the sums and clears them."""
    wp.set_module_options({"enable_backward": False})  # forward only: no adjoint code to compile

    @wp.struct
    class Bed:
        r: float
        dt: float  # the solver's step (DEM: the substep)
        e: float
        mu: float
        width: float  # the box: planes y = 0, x = 0, x = width, z = 0, z = width
        reach: float  # the gather's radius, 2 r + skin
        rest_speed: float
        g: wp.vec3
        kn: float  # DEM, per unit mass: normal stiffness (1/s^2),
        cn: float  # pair normal damping (1/s; restitution e by the spring-dashpot law),
        cn_wall: float  # the same against a plane (the particle's whole mass),
        ct: float  # tangential viscous damping (1/s), capped by Coulomb (mu times normal)

    @wp.kernel
    def layer_step(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), dt: float, r: float, e: float,
                   mu: float):
        i = wp.tid()
        vi = v[i] + wp.vec3(0.0, -9.81, 0.0) * dt
        xi = x[i] + vi * dt
        if xi[1] < r:
            xi = wp.vec3(xi[0], r, xi[2])
            vn = vi[1]
            if vn < 0.0:
                dvn = -(1.0 + e) * vn
                vt = wp.vec3(vi[0], 0.0, vi[2])
                speed = wp.length(vt)
                scale = 0.0
                if speed > 0.0:
                    scale = wp.max(0.0, 1.0 - mu * dvn / speed)
                vi = vt * scale + wp.vec3(0.0, -e * vn, 0.0)
        x[i] = xi
        v[i] = vi

    # ---- the box
    @wp.func
    def plane_normal(k: int):
        if k == 0:
            return wp.vec3(0.0, 1.0, 0.0)
        if k == 1:
            return wp.vec3(1.0, 0.0, 0.0)
        if k == 2:
            return wp.vec3(-1.0, 0.0, 0.0)
        if k == 3:
            return wp.vec3(0.0, 0.0, 1.0)
        return wp.vec3(0.0, 0.0, -1.0)

    @wp.func
    def plane_gap(k: int, p: wp.vec3, b: Bed):
        """Clearance between a particle at p and plane k (negative: overlap)."""
        c = float(0.0)
        if k == 2 or k == 4:
            c = b.width
        return wp.dot(plane_normal(k), p) + c - b.r

    # ---- the one gather a step the three share
    @wp.func
    def warm_start(i: int, c: int, j: int, n: wp.vec3, warm: float, nbr_old: wp.array2d(dtype=wp.int32),
                   count_old: wp.array(dtype=wp.int32), lam_old: wp.array2d(dtype=float),
                   lam_t_old: wp.array2d(dtype=wp.vec3), lam: wp.array2d(dtype=float),
                   lam_t: wp.array2d(dtype=wp.vec3)):
        """Slot c of row i (entry j, normal n) starts from warm times its impulses of the step
        before, if j was in row i then (the friction one kept in the new tangent plane), else 0;
        returns that impulse on particle i."""
        ln = float(0.0)
        lt = wp.vec3(0.0)
        for s in range(count_old[i]):
            if nbr_old[i, s] == j:
                ln = warm * lam_old[i, s]
                lt = warm * lam_t_old[i, s]
                lt = lt - wp.dot(lt, n) * n
        lam[i, c] = ln
        lam_t[i, c] = lt
        return ln * n + lt

    @wp.kernel
    def gather(grid: wp.uint64, x: wp.array(dtype=wp.vec3), b: Bed, nbr: wp.array2d(dtype=wp.int32),
               count: wp.array(dtype=wp.int32), dropped: wp.array(dtype=wp.int32), warm: float,
               nbr_old: wp.array2d(dtype=wp.int32), count_old: wp.array(dtype=wp.int32),
               lam_old: wp.array2d(dtype=float), lam_t_old: wp.array2d(dtype=wp.vec3),
               lam: wp.array2d(dtype=float), lam_t: wp.array2d(dtype=wp.vec3), split: wp.array(dtype=wp.int32),
               dv: wp.array(dtype=wp.vec3)):
        """Row i of the step's half list: the planes within the skin, then the particles j > i
        within reach (one hash grid query); a full row counts into `dropped`. With warm >= 0
        (impulse), also: every entry's warm start (summed into dv), and split, the number of
        entries each particle is in (its mass split; split and dv cleared before)."""
        i = wp.tid()
        xi = x[i]
        skin = b.reach - 2.0 * b.r
        c = int(0)
        dvi = wp.vec3(0.0)
        for k in range(5):
            if plane_gap(k, xi, b) < skin:
                nbr[i, c] = -1 - k
                if warm >= 0.0:
                    dvi += warm_start(i, c, -1 - k, plane_normal(k), warm, nbr_old, count_old, lam_old, lam_t_old,
                                      lam, lam_t)
                c += 1
        cap = nbr.shape[1]
        reach2 = b.reach * b.reach
        query = wp.hash_grid_query(grid, xi, b.reach)
        j = int(0)
        while wp.hash_grid_query_next(query, j):
            if j > i:
                d = xi - x[j]
                d2 = wp.length_sq(d)
                if d2 < reach2:
                    if c < cap:
                        nbr[i, c] = j
                        if warm >= 0.0:
                            imp = warm_start(i, c, j, d / wp.sqrt(wp.max(d2, 1.0e-20)), warm, nbr_old, count_old,
                                             lam_old, lam_t_old, lam, lam_t)
                            dvi += imp
                            wp.atomic_sub(dv, j, imp)
                            wp.atomic_add(split, j, 1)
                        c += 1
                    else:
                        wp.atomic_add(dropped, 0, 1)
        count[i] = c
        if warm >= 0.0:
            wp.atomic_add(split, i, c)
            wp.atomic_add(dv, i, dvi)

    # ---- pbd: position-based Jacobi
    @wp.kernel
    def pbd_predict(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), b: Bed, xp: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        vi = v[i] + b.g * b.dt
        v[i] = vi  # the velocity before contacts (restitution reads it)
        xp[i] = x[i] + vi * b.dt

    @wp.kernel
    def pbd_pairs(x: wp.array(dtype=wp.vec3), xp: wp.array(dtype=wp.vec3), nbr: wp.array2d(dtype=wp.int32),
                  count: wp.array(dtype=wp.int32), b: Bed, delta: wp.array(dtype=wp.vec3),
                  hits: wp.array(dtype=wp.int32)):
        """A Jacobi pass's corrections: each overlapping pair moves apart by half its overlap each,
        and positional friction undoes the pair's relative tangential move this step, up to mu
        times the overlap (static below it)."""
        i = wp.tid()
        xi = xp[i]
        di = xi - x[i]
        two_r = 2.0 * b.r
        acc = wp.vec3(0.0)
        m = int(0)
        for s in range(count[i]):
            j = nbr[i, s]
            if j >= 0:
                xj = xp[j]
                d = xi - xj
                d2 = wp.length_sq(d)
                if d2 < two_r * two_r and d2 > 1.0e-20:
                    dist = wp.sqrt(d2)
                    n = d / dist
                    pen = two_r - dist
                    rel = di - (xj - x[j])
                    t = rel - wp.dot(rel, n) * n
                    tl = wp.length(t)
                    corr = (0.5 * pen) * n
                    if tl > 0.0:
                        corr -= (0.5 * wp.min(1.0, b.mu * pen / tl)) * t
                    acc += corr
                    m += 1
                    wp.atomic_sub(delta, j, corr)
                    wp.atomic_add(hits, j, 1)
        if m > 0:
            wp.atomic_add(delta, i, acc)
            wp.atomic_add(hits, i, m)

    @wp.kernel
    def pbd_apply(x: wp.array(dtype=wp.vec3), xp: wp.array(dtype=wp.vec3), delta: wp.array(dtype=wp.vec3),
                  hits: wp.array(dtype=wp.int32), b: Bed, omega: float):
        """Particle i moves by omega times the mean of its pairs' corrections, then out of the
        planes (with the same positional friction against them)."""
        i = wp.tid()
        xi = xp[i]
        m = hits[i]
        if m > 0:
            xi += delta[i] * (omega / float(m))
            delta[i] = wp.vec3(0.0)
            hits[i] = 0
        for k in range(5):
            gap = plane_gap(k, xi, b)
            if gap < 0.0:
                n = plane_normal(k)
                xi -= gap * n
                t = xi - x[i]
                t -= wp.dot(t, n) * n
                tl = wp.length(t)
                if tl > 0.0:
                    xi -= wp.min(1.0, b.mu * (-gap) / tl) * t
        xp[i] = xi

    @wp.kernel
    def pbd_bounce(x: wp.array(dtype=wp.vec3), xp: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                   nbr: wp.array2d(dtype=wp.int32), count: wp.array(dtype=wp.int32), b: Bed,
                   dv: wp.array(dtype=wp.vec3), hits: wp.array(dtype=wp.int32)):
        """Restitution: a touching pair that approached faster than rest_speed before the step
        should leave at e times that speed; each gets half the missing normal velocity."""
        i = wp.tid()
        inv_dt = 1.0 / b.dt
        xi = xp[i]
        vi = (xi - x[i]) * inv_dt
        touch = 2.0 * b.r * 1.001
        acc = wp.vec3(0.0)
        m = int(0)
        for s in range(count[i]):
            j = nbr[i, s]
            if j >= 0:
                d = xi - xp[j]
                d2 = wp.length_sq(d)
                if d2 < touch * touch and d2 > 1.0e-20:
                    n = d / wp.sqrt(d2)
                    vn0 = wp.dot(v[i] - v[j], n)
                    if vn0 < -b.rest_speed:
                        vn = wp.dot(vi - (xp[j] - x[j]) * inv_dt, n)
                        target = -b.e * vn0
                        if vn < target:
                            corr = (0.5 * (target - vn)) * n
                            acc += corr
                            m += 1
                            wp.atomic_sub(dv, j, corr)
                            wp.atomic_add(hits, j, 1)
        if m > 0:
            wp.atomic_add(dv, i, acc)
            wp.atomic_add(hits, i, m)

    @wp.kernel
    def pbd_velocity(x: wp.array(dtype=wp.vec3), xp: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                     dv: wp.array(dtype=wp.vec3), hits: wp.array(dtype=wp.int32), b: Bed):
        """The velocity the step's move implies, plus the mean of the restitution corrections;
        the planes' restitution likewise (the velocity before the step is v's old value)."""
        i = wp.tid()
        xi = xp[i]
        vi = (xi - x[i]) * (1.0 / b.dt)
        m = hits[i]
        if m > 0:
            vi += dv[i] / float(m)
            dv[i] = wp.vec3(0.0)
            hits[i] = 0
        for k in range(5):
            if plane_gap(k, xi, b) < 1.0e-3 * b.r:
                n = plane_normal(k)
                vn0 = wp.dot(v[i], n)
                vn = wp.dot(vi, n)
                if vn0 < -b.rest_speed and vn < -b.e * vn0:
                    vi += (-b.e * vn0 - vn) * n
        v[i] = vi

    # ---- impulse: Jacobi impulses with mass splitting and warm starting
    @wp.kernel
    def impulse_begin(v: wp.array(dtype=wp.vec3), v0: wp.array(dtype=wp.vec3), dv: wp.array(dtype=wp.vec3),
                      b: Bed):
        """Gravity (v0: the velocity before contacts), then the warm start the gather summed."""
        i = wp.tid()
        vi = v[i] + b.g * b.dt
        v0[i] = vi
        v[i] = vi + dv[i]
        dv[i] = wp.vec3(0.0)

    @wp.kernel
    def impulse_pairs(x: wp.array(dtype=wp.vec3), v0: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3),
                      nbr: wp.array2d(dtype=wp.int32), count: wp.array(dtype=wp.int32),
                      split: wp.array(dtype=wp.int32), b: Bed, push: float, lam: wp.array2d(dtype=float),
                      lam_t: wp.array2d(dtype=wp.vec3), dv: wp.array(dtype=wp.vec3), dx: wp.array(dtype=wp.vec3)):
        """A Jacobi iteration's impulses. Each listed contact moves its accumulated normal impulse
        (>= 0) toward a target normal velocity: e times the approach speed before the step if
        that was above rest_speed and closes the gap within the step (a bounce); else a
        separated pair may close at most its gap and a touching one stops approaching. Then its
        accumulated friction impulse toward no sliding, within mu times the normal one
        (Coulomb). Mass splitting: a change is divided by the two particles' list counts (a
        plane counts 0), which keeps the Jacobi sums stable; the pair's impulses are equal and
        opposite. push > 0 (the first iteration): overlaps are also pushed apart in position,
        split the same way, never through the velocity (a bias velocity would be kept by the
        warm start and pump energy: measured, the bed boiled)."""
        i = wp.tid()
        xi = x[i]
        vi = v[i]
        v0i = v0[i]
        si = float(split[i])
        inv_dt = 1.0 / b.dt
        two_r = 2.0 * b.r
        acc = wp.vec3(0.0)
        move = wp.vec3(0.0)
        for s in range(count[i]):
            j = nbr[i, s]
            n = wp.vec3(0.0)
            gap = float(0.0)
            vrel = vi
            vrel0 = v0i
            denom = si
            if j >= 0:
                d = xi - x[j]
                dist = wp.length(d)
                n = d / wp.max(dist, 1.0e-12)
                gap = dist - two_r
                vrel = vi - v[j]
                vrel0 = v0i - v0[j]
                denom = si + float(split[j])
            else:
                n = plane_normal(-1 - j)
                gap = plane_gap(-1 - j, xi, b)
            vn = wp.dot(vrel, n)
            vn0 = wp.dot(vrel0, n)
            target = -gap * inv_dt  # separated: the most it may close
            if vn0 < -b.rest_speed and vn0 < target:  # it hits in the step: the bounce
                target = -b.e * vn0
            elif gap <= 0.0:  # touching: stop (no bias velocity)
                target = 0.0
            if gap <= 0.0:
                if push > 0.0:
                    step = (-push * gap / denom) * n
                    move += step
                    if j >= 0:
                        wp.atomic_sub(dx, j, step)
            old = lam[i, s]
            new = wp.max(old + (target - vn) / denom, 0.0)
            lam[i, s] = new
            old_t = lam_t[i, s]
            new_t = old_t - (vrel - vn * n) / denom
            cap = b.mu * new
            lt = wp.length(new_t)
            if lt > cap:
                new_t = new_t * (cap / lt)
            lam_t[i, s] = new_t
            imp = (new - old) * n + (new_t - old_t)
            acc += imp
            if j >= 0:
                wp.atomic_sub(dv, j, imp)
        wp.atomic_add(dv, i, acc)
        if push > 0.0:
            wp.atomic_add(dx, i, move)

    @wp.kernel
    def impulse_apply(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), dv: wp.array(dtype=wp.vec3),
                      dx: wp.array(dtype=wp.vec3), b: Bed, push: float, last: int):
        """Adds the iteration's impulses (and pushes); after the last one, advances the position."""
        i = wp.tid()
        vi = v[i] + dv[i]
        dv[i] = wp.vec3(0.0)
        v[i] = vi
        xi = x[i]
        if push > 0.0:
            xi += dx[i]
            dx[i] = wp.vec3(0.0)
        if last != 0:
            xi += vi * b.dt
        if push > 0.0 or last != 0:
            x[i] = xi

    # ---- dem: linear spring-dashpot, Coulomb friction, symplectic Euler substeps
    @wp.kernel
    def dem_pairs(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), nbr: wp.array2d(dtype=wp.int32),
                  count: wp.array(dtype=wp.int32), b: Bed, acc: wp.array(dtype=wp.vec3)):
        """The contact forces (per unit mass) at the substep's start: normal kn overlap - cn
        approach speed, never pulling; tangential ct times the sliding speed, at most mu times
        the normal (Coulomb), against it."""
        i = wp.tid()
        xi = x[i]
        vi = v[i]
        two_r = 2.0 * b.r
        ai = wp.vec3(0.0)
        for s in range(count[i]):
            j = nbr[i, s]
            n = wp.vec3(0.0)
            pen = float(0.0)
            vrel = vi
            cn = b.cn_wall
            if j >= 0:
                d = xi - x[j]
                d2 = wp.length_sq(d)
                if d2 < two_r * two_r and d2 > 1.0e-20:
                    dist = wp.sqrt(d2)
                    n = d / dist
                    pen = two_r - dist
                    vrel = vi - v[j]
                    cn = b.cn
            else:
                n = plane_normal(-1 - j)
                pen = -plane_gap(-1 - j, xi, b)
            if pen > 0.0:
                vn = wp.dot(vrel, n)
                fn = wp.max(b.kn * pen - cn * vn, 0.0)
                vt = vrel - vn * n
                vtl = wp.length(vt)
                f = fn * n
                if vtl > 0.0:
                    f -= (wp.min(b.ct * vtl, b.mu * fn) / vtl) * vt
                ai += f
                if j >= 0:
                    wp.atomic_sub(acc, j, f)
        wp.atomic_add(acc, i, ai)

    @wp.kernel
    def dem_advance(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), acc: wp.array(dtype=wp.vec3), b: Bed):
        """Symplectic Euler over the substep; clears the forces."""
        i = wp.tid()
        vi = v[i] + (b.g + acc[i]) * b.dt
        acc[i] = wp.vec3(0.0)
        v[i] = vi
        x[i] = x[i] + vi * b.dt

    return {"Bed": Bed, "layer_step": layer_step, "gather": gather, "pbd_predict": pbd_predict,
            "pbd_pairs": pbd_pairs, "pbd_apply": pbd_apply, "pbd_bounce": pbd_bounce, "pbd_velocity": pbd_velocity,
            "impulse_begin": impulse_begin, "impulse_pairs": impulse_pairs, "impulse_apply": impulse_apply,
            "dem_pairs": dem_pairs, "dem_advance": dem_advance}


def warp_layer(wp, kernels, n: int, frames: int, device: str) -> dict:
    layer_step = kernels["layer_step"]
    x = wp.array(layer_positions(n).astype(np.float32), dtype=wp.vec3, device=device)
    v = wp.zeros(n, dtype=wp.vec3, device=device)
    for _ in range(2 * SUBSTEPS):
        wp.launch(layer_step, dim=n, inputs=[x, v, DT, R, E, MU], device=device)
    wp.synchronize_device(device)
    t0 = time.perf_counter()
    for _ in range(frames * SUBSTEPS):
        wp.launch(layer_step, dim=n, inputs=[x, v, DT, R, E, MU], device=device)
    wp.synchronize_device(device)
    seconds = time.perf_counter() - t0
    return {"rate": n * SUBSTEPS * frames / seconds, "seconds": seconds, "lowest": float(x.numpy()[:, 1].min())}


def dem_parameters() -> dict:
    """The DEM's constants per unit mass, from DEM's stiffness and a particle's mass: dashpots
    that give restitution E for a pair (reduced mass m / 2) and against a plane (mass m)."""
    mass = DEM_DENSITY * 4.0 / 3.0 * np.pi * R ** 3
    kn = DEM["stiffness"] / mass
    zeta = -np.log(E) / np.sqrt(np.pi ** 2 + np.log(E) ** 2)  # the damping ratio for restitution E
    return {"kn": kn, "cn": 2.0 * zeta * np.sqrt(kn / 2.0), "cn_wall": 2.0 * zeta * np.sqrt(kn),
            "ct": 2.0 * zeta * np.sqrt(kn / 2.0), "dt": DT / DEM["substeps"],
            "contact_time": np.pi / np.sqrt(2.0 * kn)}  # a pair's contact, undamped


def bed_constants(wp, kernels, variant: str, width: float, reach: float):
    """The Bed struct the variant's kernels read."""
    b = kernels["Bed"]()
    b.r, b.e, b.mu, b.width, b.reach = R, E, MU, float(width), float(reach)
    b.rest_speed, b.g, b.dt = REST_SPEED, wp.vec3(*GRAVITY), DT
    if variant == "dem":
        dem = dem_parameters()
        b.kn, b.cn, b.cn_wall, b.ct, b.dt = dem["kn"], dem["cn"], dem["cn_wall"], dem["ct"], dem["dt"]
    return b


def warp_bed(wp, kernels, variant: str, n: int, settle: int, timed: int, device: str) -> dict:
    """One Warp solver on the bed: `settle` steps, then `timed` steps between two synchronizes.
    Every step: one hash grid build and one gather of the half list, then the variant's
    passes over that list: launches only, no host reads or copies. The result: the rate, the
    mean overlap and the largest speed at the end, and list entries dropped (full rows; 0)."""
    K = kernels
    positions, width = bed_positions(n)
    reach = 2.0 * R + {"pbd": PBD, "impulse": IMPULSE, "dem": DEM}[variant]["skin"]
    b = bed_constants(wp, K, variant, width, reach)
    impulse = variant == "impulse"

    def zeros(shape, dtype=wp.vec3):
        return wp.zeros(shape, dtype=dtype, device=device)

    x = wp.array(positions.astype(np.float32), dtype=wp.vec3, device=device)
    v = zeros(n)
    acc, hits = zeros(n), zeros(n, wp.int32)  # a pass's sums over pairs, cleared where applied
    xp = zeros(n)  # pbd: the predicted positions the passes move
    v0, split, dx = zeros(n), zeros(n, wp.int32), zeros(n)  # impulse: see impulse_pairs
    dropped = zeros(1, wp.int32)
    # (row entries, row lengths, impulses, friction impulses): the step's half list and, for the
    # impulse solver's warm start, the step before's
    slots = (n, CAPACITY) if impulse else (1, 1)
    lists = [(zeros((n, CAPACITY), wp.int32), zeros(n, wp.int32), zeros(slots, float), zeros(slots))
             for _ in range(2 if impulse else 1)]
    # cells twice the reach: a query reads 8 cells at most (27 with cells of the reach: slower);
    # a hashed grid whose dims cover the box (the 128^3 default cleared 16 MB every build)
    cell = 2.0 * reach
    top = float(positions[:, 1].max()) + R
    grid = wp.HashGrid(*[min(256, int(np.ceil(s / cell)) + 1) for s in (width, top, width)], device=device)

    def gather(points):
        lists.reverse()
        (nbr, count, lam, lam_t), (nbr_old, count_old, lam_old, lam_t_old) = lists[0], lists[-1]
        grid.build(points, cell)
        if impulse:
            split.zero_()
        wp.launch(K["gather"], dim=n, inputs=[grid.id, points, b, nbr, count, dropped, IMPULSE["warm"] if impulse
                                             else -1.0, nbr_old, count_old, lam_old, lam_t_old, lam, lam_t, split,
                                             acc], device=device)
        return nbr, count, lam, lam_t

    def step():
        nonlocal x, xp
        if variant == "pbd":
            wp.launch(K["pbd_predict"], dim=n, inputs=[x, v, b, xp], device=device)
            nbr, count, _, _ = gather(xp)
            for _ in range(PBD["passes"]):
                wp.launch(K["pbd_pairs"], dim=n, inputs=[x, xp, nbr, count, b, acc, hits], device=device)
                wp.launch(K["pbd_apply"], dim=n, inputs=[x, xp, acc, hits, b, PBD["omega"]], device=device)
            wp.launch(K["pbd_bounce"], dim=n, inputs=[x, xp, v, nbr, count, b, acc, hits], device=device)
            wp.launch(K["pbd_velocity"], dim=n, inputs=[x, xp, v, acc, hits, b], device=device)
            x, xp = xp, x
        elif variant == "impulse":
            nbr, count, lam, lam_t = gather(x)
            wp.launch(K["impulse_begin"], dim=n, inputs=[v, v0, acc, b], device=device)
            for it in range(IMPULSE["iterations"]):
                push, last = (IMPULSE["push"] if it == 0 else 0.0), int(it == IMPULSE["iterations"] - 1)
                wp.launch(K["impulse_pairs"], dim=n, inputs=[x, v0, v, nbr, count, split, b, push, lam, lam_t, acc,
                                                            dx], device=device)
                wp.launch(K["impulse_apply"], dim=n, inputs=[x, v, acc, dx, b, push, last], device=device)
        else:
            nbr, count, _, _ = gather(x)
            for _ in range(DEM["substeps"]):
                wp.launch(K["dem_pairs"], dim=n, inputs=[x, v, nbr, count, b, acc], device=device)
                wp.launch(K["dem_advance"], dim=n, inputs=[x, v, acc, b], device=device)

    for _ in range(settle):
        step()
    wp.synchronize_device(device)
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(timed):
        step()
    wp.synchronize_device(device)
    seconds = time.perf_counter() - t0
    # (cpu_seconds: this process's CPU time, for a loaded machine; Warp's CPU backend is one thread)
    cpu = time.process_time() - c0
    out = {"rate": n * timed / seconds, "seconds": seconds, "cpu_seconds": cpu, **work(cpu, n, timed),
           **contacts(overlap_of(x.numpy().astype(np.float64)), n),
           **speeds(v.numpy()),
           "dropped": int(dropped.numpy()[0])}
    return out


def speeds(v: np.ndarray) -> dict:
    """The largest speed, and the 99th percentile (a few particles still rolling off, or many
    moving: an explosion)."""
    speed = np.linalg.norm(v, axis=1)
    return {"max_speed": float(speed.max()), "speed_p99": float(np.percentile(speed, 99))}


def overlap_of(x: np.ndarray) -> dict:
    """Scene.particle_overlap of particles of radius R at x: the measure of tai_coll's own
    side, so that both sides are measured alike."""
    scene = tc.Scene()
    scene.add_particles(positions=x, radius=R)
    return scene.particle_overlap()


def contacts(overlap: dict, n: int) -> dict:
    """A bed's contacts at the end, from Scene.particle_overlap: the mean overlap of touching
    pairs relative to the radius, and the touching pairs a particle (how far the bed has packed,
    the work each pair pass has: the sides' beds need not be equally packed after the same
    steps)."""
    return {"mean_overlap": overlap["mean"], "touching_per_particle": overlap["pairs"] / n}


def work(cpu_seconds: float, n: int, steps: int) -> dict:
    """The process's CPU time a particle-step in ns (every thread counted: Warp's CPU backend
    runs one, tai_coll's as many as asked)."""
    return {"cpu_ns_per_particle_step": cpu_seconds / (n * steps) * 1e9}


# ---------------------------------------------------------------------- main
WARP_NOTES = {
    "pbd": lambda: f"PBD Jacobi, {PBD['passes']} passes, SOR {PBD['omega']}",
    "impulse": lambda: f"impulse Jacobi, {IMPULSE['iterations']} iterations, warm-started",
    "dem": lambda: (f"linear DEM, k {DEM['stiffness']:g} N/m, {DEM['substeps']} substeps "
                    f"({dem_parameters()['dt'] * 1e6:.0f} us)"),
}


def bed_row(n: int, method: str, ours: dict, theirs: dict) -> dict:
    """The bed's JSON row for one of tai_coll's pass methods: every Warp variant's figures and
    tai_coll's ratio to each, and to the fastest of them (Warp's best; the overlaps stand beside
    the rates, not in the choice)."""
    best = max(theirs, key=lambda k: theirs[k]["rate"])
    return {"row": "bed", "particles": n, "method": method, "tai_coll": ours, "warp": theirs,
            "ratio": {k: ours["rate"] / t["rate"] for k, t in theirs.items()},
            "warp_best": best, "ratio_to_best": ours["rate"] / theirs[best]["rate"]}


def headline_ratio(row: dict) -> float:
    """A row's ratio: the layer's against Warp, the bed's against Warp's best."""
    return row["ratio"] if row["row"] == "layer" else row["ratio_to_best"]


def median_rows(runs: list) -> list:
    """One row per (row, particles, method) from the runs of every repeat: the run of median
    ratio (the lower middle one for an even count), with the ratios of all its runs (`runs`,
    in the order run) and their range."""
    keyed = {}
    for run in runs:
        keyed.setdefault((run["row"], run["particles"], run.get("method")), []).append(run)
    rows = []
    for same in keyed.values():
        ordered = sorted(same, key=headline_ratio)
        ratios = [headline_ratio(run) for run in same]
        rows.append({**ordered[(len(ordered) - 1) // 2], "runs": ratios, "ratio_range": [min(ratios), max(ratios)]})
    return rows


def print_table(rows: list, header: str) -> None:
    print(header)
    print(f"{'row':<6} {'particles':>10}  {'solver':<9} {'steps/s':>10} {'tai_coll/it':>11} {'overlap':>8} "
          f"{'max speed':>10}  notes")

    def spread(r):
        runs = r.get("runs", [])
        return (f"; the median of {len(runs)} runs, ratios {r['ratio_range'][0]:.2f}x to {r['ratio_range'][1]:.2f}x"
                if len(runs) > 1 else "")

    def held(res):  # bytes a particle, and the largest scene the memory holds
        big = res["largest"]
        limit = "" if big["limit"] == "memory" else f", by the {big['limit']}"
        return (f"{res['state_bytes_per_particle']:.0f} B a particle: {big['particles'] / 1e6:,.1f}M in "
                f"{big['memory_gb']:g} GB{limit}")

    def packing(res):  # touching pairs and CPU time, a particle
        return (f"{res['touching_per_particle']:.2f} touching pairs a particle, "
                f"{res['cpu_ns_per_particle_step']:.0f} ns of CPU a particle-step")

    def line(row, particles, solver, res, ratio, notes):
        overlap = f"{res['mean_overlap'] * 100:.2f}%r" if "mean_overlap" in res else ""
        speed = f"{res['max_speed']:.3f}m/s" if "max_speed" in res else ""
        ratio = f"{ratio:.2f}x" if ratio is not None else ""
        print(f"{row:<6} {particles:>10}  {solver:<9} {res['rate']:>10.3e} {ratio:>11} {overlap:>8} {speed:>10}  "
              f"{notes}")

    for r in rows:
        if r["row"] == "layer":
            line("layer", f"{r['particles']:,}", "tai_coll", r["tai_coll"], None,
                 f"lowest centre {r['tai_coll']['lowest'] * 1e3:.3f} mm; {held(r['tai_coll'])}")
            line("", "", "warp", r["warp"], r["ratio"], f"one kernel a step; lowest centre "
                 f"{r['warp']['lowest'] * 1e3:.3f} mm{spread(r)}")
            continue
        method = pair_options(r["method"])
        passes = (f", {method['iterations']} contact and {method['projection_iterations']} projection passes"
                  if "iterations" in method else "")
        name = {"gauss-seidel": "Gauss-Seidel impulses", "jacobi": "Jacobi impulses"}[method["method"]]
        line("bed", f"{r['particles']:,}", "tai_coll", r["tai_coll"], None,
             f"{name}{passes}{' (default)' if r['method'] == 'gauss-seidel' else ''}; {packing(r['tai_coll'])}; "
             f"{held(r['tai_coll'])}")
        for k, res in r["warp"].items():
            notes = WARP_NOTES[k]() + f"; {packing(res)}" + (
                f"; {res['dropped']} list entries dropped!" if res["dropped"] else "")
            line("", "", k, res, r["ratio"][k], notes)
        print(f"{'':<6} {'':>10}  tai_coll against Warp's best ({r['warp_best']}): {r['ratio_to_best']:.2f}x"
              f"{spread(r)}")


def gigabytes(text: str) -> float:
    """A positive size in GB (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a size in GB such as 80; got {text!r}")
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive, finite size in GB; got {text!r}")
    return value


def sizes(text: str) -> list:
    """A comma-separated list of particle counts (argparse type)."""
    try:
        counts = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected particle counts such as 1000000,10000000; got {text!r}")
    if not counts or min(counts) < 1:
        raise argparse.ArgumentTypeError(f"expected positive particle counts; got {text!r}")
    return counts


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", default="layer,bed")
    parser.add_argument("--layer-particles", type=sizes, default=[1_000_000],
                        help="layer sizes, comma-separated (default 1000000)")
    parser.add_argument("--layer-frames", type=count(), default=10)
    parser.add_argument("--bed-particles", type=sizes, default=[100_000],
                        help="bed sizes, comma-separated (default 100000)")
    parser.add_argument("--settle", type=count(0), default=300,
                        help=f"bed: steps to settle, a multiple of {SUBSTEPS} (default 300)")
    parser.add_argument("--timed", type=count(SUBSTEPS), default=100,
                        help=f"bed: steps timed, a multiple of {SUBSTEPS} (default 100)")
    parser.add_argument("--warp-variants", default=",".join(WARP_VARIANTS),
                        help="bed: Warp's solvers, any of pbd,impulse,dem (default all three)")
    parser.add_argument("--pair-methods", default="gauss-seidel",
                        help="bed: tai_coll's pass methods, any of gauss-seidel,jacobi, each optionally with its "
                             "contact and projection passes (jacobi:2:10); default gauss-seidel")
    parser.add_argument("--repeats", type=count(), default=1,
                        help="run every row this many times, tai_coll and Warp alternately; each row reports the "
                             "run of median ratio and the ratios' range (default 1)")
    parser.add_argument("--arch", default="cpu", choices=("cpu", "cuda"),
                        help="both sides on the CPU or on the first CUDA GPU (default cpu)")
    parser.add_argument("--threads", type=count(), default=2)
    parser.add_argument("--memory-gb", type=gigabytes, default=80.0,
                        help="report the largest scene of each row that this memory holds (10^9 B; default 80)")
    parser.add_argument("--out", default=str(ROOT / "bench_results" / "bench_warp.json"))
    args = parser.parse_args(argv)
    wanted = [r for r in args.rows.split(",") if r]
    if not wanted or set(wanted) - {"layer", "bed"}:
        parser.error(f"--rows: choose from layer,bed; got {args.rows!r}")
    for option, steps in (("--settle", args.settle), ("--timed", args.timed)):
        if steps % SUBSTEPS:
            parser.error(f"{option}: tai_coll's bed steps frames of {SUBSTEPS} steps: give a multiple of "
                         f"{SUBSTEPS}; got {steps}")
    variants = [v for v in args.warp_variants.split(",") if v]
    unknown = sorted(set(variants) - set(WARP_VARIANTS))
    if unknown or not variants:
        parser.error(f"--warp-variants: choose from {','.join(WARP_VARIANTS)}; got {args.warp_variants!r}")
    methods = [m for m in args.pair_methods.split(",") if m]
    try:
        if not methods:
            raise ValueError("give at least one")
        for m in methods:
            pair_options(m)
    except ValueError as error:
        parser.error(f"--pair-methods: {error}")
    report_path(parser, "--out", args.out)
    try:
        import warp as wp
    except ImportError:
        sys.exit("bench_warp: needs warp-lang (a benchmark-only extra): pip install 'tai_coll[bench]'")
    landed = tc.init(arch=args.arch, threads=args.threads if args.arch == "cpu" else None).arch
    if landed != args.arch:  # (Taichi falls back to the CPU where CUDA cannot start)
        sys.exit(f"bench_warp: --arch {args.arch}: Taichi could not start it here and runs on {landed}; "
                 f"the two sides would not share a device")
    wp.config.quiet = True
    wp.init()
    device = "cpu" if args.arch == "cpu" else "cuda:0"
    kernels = warp_kernels(wp)
    rows = []
    settings = {"pbd": PBD, "impulse": IMPULSE, "dem": {**DEM, "density": DEM_DENSITY, **dem_parameters()},
                "rest_speed": REST_SPEED, "list_capacity": CAPACITY}
    report = {"benchmark": "bench_warp", "machine": machine_info(args), "warp": wp.__version__,
              "warp_settings": settings, "rows": rows}

    runs = []  # every run of every row, in the order run

    def done(row):  # every row written as it is finished (a long GPU run may be cut short)
        runs.append(row)
        rows[:] = median_rows(runs)
        write_json(args.out, report)
        print(f"  done: {row['row']} of {row['particles']:,}", flush=True)

    for _ in range(args.repeats):
        if "layer" in wanted:
            for n in args.layer_particles:
                ours = tai_coll_layer(n, args.layer_frames)
                ours["largest"] = largest_scene(ours["state_bytes_per_particle"], args.memory_gb, pairs=False)
                theirs = warp_layer(wp, kernels, n, args.layer_frames, device)
                done({"row": "layer", "particles": n, "tai_coll": ours, "warp": theirs,
                      "ratio": ours["rate"] / theirs["rate"]})
        if "bed" in wanted:
            for n in args.bed_particles:
                ours = {m: tai_coll_bed(n, args.settle, args.timed, m) for m in methods}
                for res in ours.values():
                    res["largest"] = largest_scene(res["state_bytes_per_particle"], args.memory_gb, pairs=True)
                theirs = {k: warp_bed(wp, kernels, k, n, args.settle, args.timed, device) for k in variants}
                for m in methods:
                    done(bed_row(n, m, ours[m], theirs))
    print_table(rows, f"tai_coll {tc.__version__} ({args.arch}, {args.threads if args.arch == 'cpu' else ''} "
                      f"threads) against Warp {wp.__version__} ({device}), f32, dt {DT:.4g} s; steps/s: "
                      f"particle-steps per second (bed: steps of dt; overlap: mean of touching pairs)")
    print(f"wrote {write_json(args.out, report)}")


if __name__ == "__main__":
    main()
