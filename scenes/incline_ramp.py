"""Blocks on inclines of increasing angle against the friction coefficient (Coulomb friction).

A particle set at rest on a plank tilted by theta, with friction mu, stays put while
tan(theta) <= mu (static friction holds it: the tangential velocity change gravity gives in
a substep, g sin(theta) dt, is within mu times the normal one, mu g cos(theta) dt) and
otherwise slides down with a = g (sin(theta) - mu cos(theta)), so s = a t^2 / 2.
Two rows of planks, mu = 0.3 (critical angle 16.7 degrees) and mu = 0.6 (31.0 degrees), at
10, 20, 35 and 50 degrees; restitution 0, so nothing bounces.
Run it: `python scenes/incline_ramp.py` prints each plank's slide against the closed form.
"""

import numpy as np

import tai_coll as tc

ANGLES = np.radians([10.0, 20.0, 35.0, 50.0])
FRICTIONS = [0.3, 0.6]
G = 9.81             # m/s^2
RADIUS = 0.04        # m
HALF_LENGTH = 0.5    # m, half the plank's length along the slope
HALF_THICKNESS = 0.02
START = 0.4          # m up the slope from the plank's center
SPACING = (0.8, 0.5)  # m between planks along x (angles) and z (frictions)
FRAMES = 30          # 0.5 s at 60 frames per second: the fastest block slides 0.70 m of its 0.9 m


def planks():
    """(angle, mu, center, rotation) of every plank."""
    out = []
    for j, mu in enumerate(FRICTIONS):
        for i, theta in enumerate(ANGLES):
            center = np.array([i * SPACING[0], 1.0, j * SPACING[1]])
            out.append((theta, mu, center, tc.rotation_matrix((0.0, 0.0, 1.0), theta)))
    return out


def scene() -> tc.Scene:
    s = tc.Scene(gravity=(0.0, -G, 0.0), dt=1.0 / 1200.0, substeps=20)
    starts = []
    for theta, mu, center, rotation in planks():
        s.add_collider(tc.Box(center=center, half_extents=(HALF_LENGTH, HALF_THICKNESS, 0.15), rotation=rotation),
                       material=tc.Material(restitution=0.0, friction=mu))
        # the plank's local +x runs up the slope, local +y is its top face's normal
        starts.append(center + rotation @ np.array([START, HALF_THICKNESS + RADIUS, 0.0]))
    s.add_particles(positions=starts, radius=RADIUS)
    return s


def expected_slide(theta, mu, t):
    """Distance slid down the slope after t seconds from rest (0 while friction holds)."""
    a = G * (np.sin(theta) - mu * np.cos(theta))
    return 0.5 * max(a, 0.0) * t * t


def slides(s: tc.Scene, frames: int = FRAMES) -> np.ndarray:
    """Step the scene; return each block's displacement down its slope (m)."""
    x0 = s.positions()
    s.step(frames)
    down = np.array([-(rotation @ np.array([1.0, 0.0, 0.0])) for *_, rotation in planks()])
    return np.einsum("ij,ij->i", s.positions() - x0, down)


def check(slid: np.ndarray, t: float) -> None:
    """Static blocks move < 1 mm; sliding ones match a t^2 / 2 within 3 %."""
    for (theta, mu, *_), s in zip(planks(), slid):
        want = expected_slide(theta, mu, t)
        if want == 0.0:
            assert abs(s) < 1e-3, f"theta {np.degrees(theta):.0f} deg, mu {mu}: slid {s:.4f} m, expected to stay"
        else:
            assert abs(s - want) < 0.03 * want, f"theta {np.degrees(theta):.0f} deg, mu {mu}: slid {s:.4f} m, " \
                                                f"expected {want:.4f} m"


def main():
    s = scene()
    slid = slides(s)
    print(f"{'angle':>6} {'mu':>4} {'tan':>5}  {'slid (m)':>9}  {'a t^2/2 (m)':>11}")
    for (theta, mu, *_), d in zip(planks(), slid):
        want = expected_slide(theta, mu, s.time)
        print(f"{np.degrees(theta):6.0f} {mu:4.1f} {np.tan(theta):5.2f}  {d:9.4f}  {want:11.4f}")
    check(slid, s.time)
    print(f"simulated {s.time:.2f} s: blocks below the friction angle stay, the others slide as a t^2 / 2")


if __name__ == "__main__":
    main()
