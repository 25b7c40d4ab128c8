"""The bouncing-block problem: particles resting on bouncy surfaces (e = 0.9) must stay at rest.

Gravity pulls a resting particle into the floor a little every substep. Processing that as
a collision with restitution e reflects the small downward velocity, so the particle hops
and never settles (docs/physics.md 3, Implementation 1 fails for resting contact). The default
scheme (Implementation 3, "elastic_contact") applies the elastic law to the velocity at the
start of the substep, which is zero for a resting particle, then removes what is left of
the approach with an inelastic contact pass: resting particles stay put while particles
dropped on the same surfaces still rebound to e^2 h.

A floor plane and a box top, both e = 0.9: a grid of resting particles of three radii on
each, and a row of particles dropped from h = 0.3 m.
Run it: `python scenes/resting_restitution.py` prints how far the resting particles moved
under the default scheme and under the "simple" one, and the droppers' rebound.
"""

import numpy as np

import tai_coll as tc

RESTITUTION = 0.9
RADII = (0.01, 0.02, 0.04)   # m
DROP_HEIGHT = 0.3            # m, dropper bottom above the floor
BOX_TOP = 0.2                # m
FRAMES = 45                  # 0.75 s at 60 frames per second: every dropper reaches its first apex


def resting_positions():
    """Particles touching the floor (x < 0) and the box top (x > 0.6), bottoms exactly on them."""
    out = []
    for k, r in enumerate(RADII):
        for i in range(4):
            out.append([-0.6 + 0.15 * i, r, -0.2 + 0.2 * k])          # on the floor
            out.append([0.7 + 0.12 * i, BOX_TOP + r, -0.2 + 0.2 * k])  # on the box
    return np.array(out)


def dropper_positions():
    return np.array([[0.0 + 0.15 * i, DROP_HEIGHT + RADII[1], 0.35] for i in range(3)])


def scene(solver=None) -> tc.Scene:
    s = tc.Scene(gravity=(0.0, -9.81, 0.0), dt=1.0 / 1200.0, substeps=20, solver=solver)
    bouncy = tc.Material(restitution=RESTITUTION, friction=0.3)
    s.add_collider(tc.Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 1.0, 0.0)), material=bouncy)
    s.add_collider(tc.Box(center=(0.88, BOX_TOP / 2, 0.0), half_extents=(0.3, BOX_TOP / 2, 0.35)), material=bouncy)
    rest = resting_positions()
    radii = np.concatenate([np.repeat(RADII, 8), np.full(3, RADII[1])])
    s.add_particles(positions=np.concatenate([rest, dropper_positions()]), radius=radii)
    return s


def run(s: tc.Scene, frames: int = FRAMES):
    """Step; return (largest displacement of a resting particle over the run (m), the
    droppers' highest bottom after their first bounce (m))."""
    n_rest = len(resting_positions())
    x0 = s.positions()[:n_rest]
    drift = 0.0
    bounced = np.zeros(3, dtype=bool)
    apex = np.zeros(3)
    for _ in range(frames):
        s.step()
        x = s.positions()
        drift = max(drift, float(np.max(np.linalg.norm(x[:n_rest] - x0, axis=1))))
        bounced |= s.velocities()[n_rest:, 1] > 1e-3
        apex = np.where(bounced, np.maximum(apex, x[n_rest:, 1] - RADII[1]), apex)
    return drift, apex


def check(drift: float, apex: np.ndarray) -> None:
    """Resting particles move less than 0.1 mm; droppers rebound to e^2 h within 3 % of h."""
    assert drift < 1e-4, f"resting particles moved {drift:.3g} m with e = {RESTITUTION}"
    want = RESTITUTION ** 2 * DROP_HEIGHT
    assert np.all(np.abs(apex - want) < 0.03 * DROP_HEIGHT), f"rebound apex {apex} vs e^2 h = {want:.4f} m"


def main():
    s = scene()
    drift, apex = run(s)
    simple_drift, _ = run(scene(tc.ImpulseSolver(scheme="simple")))
    print(f"resting particles, largest displacement over {s.time:.2f} s with e = {RESTITUTION}:")
    print(f"  elastic_contact (default): {drift:.3g} m")
    print(f"  simple (Implementation 1): {simple_drift:.3g} m")
    print(f"droppers' rebound apex {np.round(apex, 4).tolist()} m vs e^2 h = {RESTITUTION ** 2 * DROP_HEIGHT:.4f} m")
    check(drift, apex)
    print("resting particles stay at rest; dropped ones still bounce")


if __name__ == "__main__":
    main()
