"""Angle of repose: beads poured from a small funnel onto a rough plate form a cone whose flank
angle is measured (DEM pairs with spinning grains and rolling resistance: docs/physics.md 5.4,
6; a calibration scene for `tai-coll sweep`).

An emitter 9 to 11 cm above the plate (a cylinder 6 cm across, the "funnel") pours 800 glass-like
beads (radii 4, 5 and 6 mm in equal numbers, so that they pack without crystallising;
2,500 kg/m^3) at 600 a second, 0.8 m/s downward, for 1.33 s; then the pile settles for 1.67 s.
The grains are DEM spring-dashpots (`tc.PenaltySolver(hertz=100, spin=True)`, docs/physics.md
5.4) with Cundall-Strack tangential springs (`tangential_springs=True`): a contact sticks while
its spring's force is within mu f_n (static friction that holds a slope, where the regularised
force would creep at g sin(theta) dt, 5.4) and each contact keeps a rolling spring capped at
mu_r l f_n (6.3). The grains spin, so `rolling_friction` (mu_r, 6.1) is the second material
parameter: a frictional sphere that may roll freely sets no slope beyond what geometry gives,
and rolling resistance is what calibrations of real grains tune along with mu.
`restitution` e sets the contact's damping ratio, zeta = -ln e / sqrt(pi^2 + ln^2 e) (the
linear spring-dashpot's rebound, 4.5; the penalty solver itself ignores Material.restitution).
The plate is rough and the same for every material (friction 1, rolling friction 1: a plate
with grains glued on, as in the fixed-funnel test): grains that reach it stop there, so the
pile's toe is the material's own and a slippery material does not run off as a carpet of
rolling beads.

DEM rather than the default impulse pairs, whose piles' angle depends on their contact passes
as much as on the material: docs/sweeps.md has the measurements behind that choice.

The angle (`metrics`): the surface grains are those with no other grain's centre above them
within half the sum of the radii horizontally; their tops (y + r) against the horizontal
distance d from the funnel's axis are fitted by a straight line in two passes: first the
grains whose tops lie between 25 % and 75 % of the pile's height, then every surface grain
whose d lies between where that line crosses those two heights. This leaves out the rounded
top under the stream and the toe; angle = atan(-slope). `radius_m` is where the line meets
the plate, `height_m` the highest top.
docs/sweeps.md sweeps friction x rolling friction (the angle rises with both; seeds scatter a
run by about 1 degree: the pile is only 4 to 6 grains high).
The first grains land on the bare plate at 1.7 m/s and press into their partners by up to 40 %
of the smaller radius for a moment, which the solver reports once as contacts too soft for
their load; at rest the deepest overlap is 15 % of a radius and the mean 1.6 %.
Run it: `python scenes/angle_of_repose.py` (the default material, then friction 0.1; checks
both piles are at rest, the angle is plausible and the rougher material stands steeper);
`tai-coll sweep scenes/angle_of_repose.py --param friction=0.1,0.3,0.5,0.8` for a table.
"""

import numpy as np

import tai_coll as tc

RADII = (0.004, 0.005, 0.006)  # m, equal numbers of each
DENSITY = 2500.0               # kg/m^3
COUNT = 800                    # grains poured
RATE = 600.0                   # grains per second: COUNT in 1.33 s
FUNNEL = tc.Cylinder(center=(0.0, 0.1, 0.0), radius=0.03, half_height=0.01)
POUR_SPEED = 0.8               # m/s, downward out of the funnel
HERTZ = 100.0                  # contact frequency; the lightest pair's dt is picked by substeps="auto"
PLATE = tc.Material(friction=1.0, rolling_friction=1.0)  # rough: the same for every material
FRAMES = 180                   # 3 s at 60 frames per second: 1.33 s of pouring; the last avalanches stop by ~2.7 s
REST_SPEED = 0.01              # m/s: the fastest grain at the end, 0.17 mm a frame
REST_ENERGY = 1e-6             # J: ~1e-6 of the pile's potential energy above the plate (0.2 J)
FLANK = (0.25, 0.75)           # the band of the pile's height whose surface grains are fitted


def damping_ratio(restitution: float) -> float:
    """The damping ratio whose linear spring-dashpot rebounds with `restitution` (1 at e = 0)."""
    if restitution == 0.0:
        return 1.0
    log_e = np.log(restitution)
    return float(-log_e / np.sqrt(np.pi ** 2 + log_e ** 2))


def scene(friction=0.5, restitution=0.2, rolling_friction=0.1, seed=0) -> tc.Scene:
    """The pour: `friction` (Coulomb mu, grain on grain), `restitution` (e of a grain pair or a
    grain on the plate, through the damping ratio), `rolling_friction` (mu_r, grain on grain),
    `seed` (the funnel's random placement)."""
    friction, restitution, rolling_friction = float(friction), float(restitution), float(rolling_friction)
    if not 0.0 <= restitution < 1.0:
        raise ValueError(f"restitution must be in [0, 1) for a damped DEM contact; got {restitution}")
    solver = tc.PenaltySolver(hertz=HERTZ, damping_ratio=damping_ratio(restitution), spin=True)
    s = tc.Scene(substeps="auto", frame_dt=1.0 / 60.0, solver=solver)
    s.add_collider(tc.Plane(), material=PLATE)
    s.enable_particle_collisions(material=tc.Material(friction=friction, rolling_friction=rolling_friction),
                                 tangential_springs=True, verlet_skin=0.001)
    for k, r in enumerate(RADII):
        share = COUNT // len(RADII) + (k < COUNT % len(RADII))
        # each size at its share of RATE; stop a little late so that a skipped placement is made up
        s.add_emitter(FUNNEL, rate=RATE * share / COUNT, stop=COUNT / RATE + 0.1, max_particles=share, radius=r,
                      mass=DENSITY * 4.0 / 3.0 * np.pi * r ** 3, velocity=(0.0, -POUR_SPEED, 0.0),
                      seed=int(seed) * len(RADII) + k)
    return s


def surface(x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(N,) bools: no other grain's centre lies above this one within half the sum of the radii
    horizontally (nothing rests on it)."""
    horizontal = np.linalg.norm(x[:, None, [0, 2]] - x[None, :, [0, 2]], axis=2)
    covered = (x[None, :, 1] > x[:, None, 1]) & (horizontal < 0.5 * (r[:, None] + r[None, :]))
    return ~covered.any(axis=1)


def flank_fit(distance: np.ndarray, top: np.ndarray, height: float):
    """(slope, intercept, used): the two-pass line fit of the surface grains' tops (see above)."""
    low, high = FLANK[0] * height, FLANK[1] * height
    band = (top > low) & (top < high)
    if band.sum() < 3:
        return np.nan, np.nan, 0
    slope, intercept = np.polyfit(distance[band], top[band], 1)
    if slope < 0.0:
        near, far = (intercept - high) / -slope, (intercept - low) / -slope
        flank = (distance > near) & (distance < far)
        if flank.sum() >= 3:
            slope, intercept = np.polyfit(distance[flank], top[flank], 1)
            band = flank
    return float(slope), float(intercept), int(band.sum())


def metrics(s: tc.Scene) -> dict:
    """Numbers read from the final state: the flank's angle and the pile's size, and how still
    it is."""
    x, v, r, m = (s.positions().astype(float), s.velocities().astype(float), s.radii().astype(float),
                  s.masses().astype(float))
    speed = np.linalg.norm(v, axis=1)
    kinetic = 0.5 * float(np.sum(m * speed ** 2))
    top = x[:, 1] + r
    distance = np.linalg.norm(x[:, [0, 2]] - np.array([FUNNEL.center[0], FUNNEL.center[2]]), axis=1)
    on_top = surface(x, r)
    height = float(top.max()) if len(top) else 0.0
    slope, intercept, used = flank_fit(distance[on_top], top[on_top], height)
    angle = float(np.degrees(np.arctan(-slope))) if np.isfinite(slope) else float("nan")
    return {"angle_deg": angle, "height_m": height,
            "radius_m": float(intercept / -slope) if np.isfinite(slope) and slope < 0 else float("nan"),
            "particles": int(len(x)), "surface_grains_fitted": used,
            "kinetic_energy_j": kinetic, "max_speed_m_s": float(speed.max()) if len(speed) else 0.0}


def render_settings() -> dict:
    """For `tai-coll run` and sweeps' contact sheets: the pile side-on, coloured by height on one
    fixed scale so that piles of different materials compare."""
    from tai_coll.render import Camera

    return {"camera": Camera(position=(0.0, 0.06, 0.8), look_at=(0.0, 0.03, 0.0), fov=19.0),
            "color_by": "height", "color_range": (0.0, 0.07), "plane_size": 0.3}


def run(**params) -> dict:
    """scene(**params) stepped FRAMES frames; its metrics."""
    s = scene(**params)
    s.step(FRAMES)
    return metrics(s)


def main():
    results = {}
    for friction in (0.5, 0.1):
        out = run(friction=friction)
        results[friction] = out
        print(f"friction {friction}: angle {out['angle_deg']:.1f} deg (fit of {out['surface_grains_fitted']} surface "
              f"grains), height {out['height_m'] * 1e3:.1f} mm, radius {out['radius_m'] * 1e3:.0f} mm, "
              f"{out['particles']} grains, kinetic energy {out['kinetic_energy_j']:.2e} J, "
              f"fastest {out['max_speed_m_s'] * 1e3:.3f} mm/s")
        assert out["particles"] == COUNT, "the funnel should pour every grain"
        # at rest: while a pile forms, its surface flows at 0.1 to 1 m/s (kinetic energy ~1e-3 J)
        assert out["max_speed_m_s"] < REST_SPEED, "the pile should be at rest"
        assert out["kinetic_energy_j"] < REST_ENERGY, "the pile should be at rest"
    rough, smooth = results[0.5]["angle_deg"], results[0.1]["angle_deg"]
    assert 15.0 < rough < 40.0, f"angle {rough:.1f} deg at friction 0.5 out of the plausible range"
    assert 0.0 < smooth < rough - 3.0, f"friction 0.1 ({smooth:.1f} deg) should stand lower than 0.5 ({rough:.1f})"
    print("both piles came to rest, and the higher friction stands steeper")


if __name__ == "__main__":
    main()
