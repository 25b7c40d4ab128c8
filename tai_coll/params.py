"""Choosing spring and damping constants and the step size (docs/physics.md 4, seed 002).

Every number here comes from the 1-D model of one contact, m a = -K x - D v:

- critical damping D_c = 2 sqrt(m K); damping ratio zeta = D / D_c;
- underdamped (zeta < 1): oscillation with natural period 2 pi sqrt(m / K), amplitude
  decaying at rate D / 2m (decay time 2m / D);
- critically damped (zeta = 1): no oscillation, the fastest decay, rate D / 2m = sqrt(K / m)
  (time 2m / D);
- overdamped (zeta > 1): no oscillation, two decay rates (D -+ sqrt(D^2 - 4 m K)) / 2m,
  close to K / D and D / m when heavily overdamped (times D / K and m / D).

The step must be a fraction of the smallest characteristic time. `recommended_dt` takes
`fraction` (0.1) of it; the explicit (symplectic Euler) integration of the contact diverges
beyond `stability_limit`. Implicit integration buys stability, not accuracy.

Host-side numpy functions of scalars (mass in kg, stiffness in N/m, damping in N s/m);
`contact()` gathers them for one contact. The seed's own warning applies: this is all very
approximate, and a real scene needs a fudge factor from experiments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from . import validate

#: recommended_dt = RECOMMENDED_FRACTION * smallest characteristic time
RECOMMENDED_FRACTION = 0.1
#: Tolerance on the damping ratio within which a contact counts as critically damped.
CRITICAL_TOLERANCE = 1e-6

UNDERDAMPED = "underdamped"
CRITICALLY_DAMPED = "critically damped"
OVERDAMPED = "overdamped"


def _mass(mass):
    return validate.real("mass", mass, low=0.0, low_open=True)


def _stiffness(stiffness):
    return validate.real("stiffness", stiffness, low=0.0, low_open=True)


def _damping(damping, mass, stiffness):
    """None: critical damping."""
    if damping is None:
        return critical_damping(mass, stiffness)
    return validate.real("damping", damping, low=0.0)


def critical_damping(mass: float, stiffness: float) -> float:
    """D_c = 2 sqrt(m K) (N s/m): the least damping without oscillation."""
    return 2.0 * math.sqrt(_mass(mass) * _stiffness(stiffness))


def damping_ratio(mass: float, stiffness: float, damping: float) -> float:
    """zeta = D / (2 sqrt(m K)): < 1 underdamped, 1 critical, > 1 overdamped."""
    return validate.real("damping", damping, low=0.0) / critical_damping(mass, stiffness)


def damping_from_ratio(mass: float, stiffness: float, ratio: float) -> float:
    """D = 2 zeta sqrt(m K) (N s/m) for damping ratio zeta."""
    return validate.real("damping_ratio", ratio, low=0.0) * critical_damping(mass, stiffness)


def stiffness_from_hertz(mass: float, hertz: float) -> float:
    """K = m (2 pi f)^2 (N/m): the stiffness that makes the undamped contact oscillate at
    `hertz` for this mass (so one frequency works across particle masses)."""
    return _mass(mass) * (2.0 * math.pi * validate.real("hertz", hertz, low=0.0, low_open=True)) ** 2


def natural_period(mass: float, stiffness: float) -> float:
    """2 pi sqrt(m / K) (s): the undamped contact's period; a bounce lasts half of it."""
    return 2.0 * math.pi * math.sqrt(_mass(mass) / _stiffness(stiffness))


def decay_time(mass: float, damping: float) -> float:
    """2m / D (s): amplitude decays as exp(-t D / 2m); inf without damping."""
    damping = validate.real("damping", damping, low=0.0)
    return math.inf if damping == 0.0 else 2.0 * _mass(mass) / damping


def regime(mass: float, stiffness: float, damping: float | None = None) -> str:
    """"underdamped", "critically damped" or "overdamped" (damping None: critical)."""
    zeta = _damping(damping, mass, stiffness) / critical_damping(mass, stiffness)
    if abs(zeta - 1.0) <= CRITICAL_TOLERANCE:
        return CRITICALLY_DAMPED
    return UNDERDAMPED if zeta < 1.0 else OVERDAMPED


def characteristic_times(mass: float, stiffness: float, damping: float | None = None) -> dict:
    """The 1-D contact's characteristic times (s) by regime, named as in seed 002:
    underdamped: "period", "decay"; critically damped: "decay"; overdamped: "slow decay"
    and "fast decay" (exact roots; close to D/K and m/D when heavily overdamped)."""
    m, k = _mass(mass), _stiffness(stiffness)
    d = _damping(damping, m, k)
    kind = regime(m, k, d)
    if kind == UNDERDAMPED:
        return {"period": natural_period(m, k), "decay": decay_time(m, d)}
    if kind == CRITICALLY_DAMPED:
        return {"decay": 2.0 * m / d}
    root = math.sqrt(d * d - 4.0 * m * k)
    slow_rate = (d - root) / (2.0 * m)
    fast_rate = (d + root) / (2.0 * m)
    # (d - root) loses digits when heavily overdamped; slow * fast = K / m is exact.
    slow_rate = k / (m * fast_rate)
    return {"slow decay": 1.0 / slow_rate, "fast decay": 1.0 / fast_rate}


def smallest_time(mass: float, stiffness: float, damping: float | None = None) -> float:
    """The smallest characteristic time (s): what the step size must be a fraction of."""
    return min(characteristic_times(mass, stiffness, damping).values())


def recommended_dt(mass: float, stiffness: float, damping: float | None = None, *,
                   fraction: float = RECOMMENDED_FRACTION) -> float:
    """`fraction` of the smallest characteristic time (s). At the default 0.1 an undamped
    bounce (half a period) takes 5 steps, and the explicit integration stays at least 2.7
    times inside its stability limit, whatever the damping."""
    fraction = validate.real("fraction", fraction, low=0.0, high=1.0, low_open=True)
    return fraction * smallest_time(mass, stiffness, damping)


def stability_limit(mass: float, stiffness: float, damping: float | None = None) -> float:
    """The largest dt (s) at which symplectic Euler (v += dt a, x += dt v) keeps the 1-D
    contact from growing: with w^2 = K/m and g = D/m, its step matrix has determinant
    1 - dt g and trace 2 - dt g - dt^2 w^2, and both roots stay in the unit circle while
    dt < (sqrt(g^2 + 4 w^2) - g) / w^2 (2 / w undamped, 0.83 / w critically damped)."""
    m, k = _mass(mass), _stiffness(stiffness)
    g = _damping(damping, m, k) / m
    w2 = k / m
    return (math.sqrt(g * g + 4.0 * w2) - g) / w2


@dataclass(frozen=True)
class ContactParams:
    """Everything `params` knows about one contact (units: kg, N/m, N s/m, s, Hz)."""

    mass: float
    stiffness: float
    damping: float
    critical_damping: float
    damping_ratio: float
    regime: str
    natural_period: float
    natural_frequency: float
    decay_time: float
    characteristic_times: dict = field(repr=False)
    smallest_time: float
    recommended_dt: float
    stability_limit: float

    def __str__(self):
        times = ", ".join(f"{name} {t:.3g} s" for name, t in self.characteristic_times.items())
        return (f"m = {self.mass:.4g} kg, k = {self.stiffness:.4g} N/m, D = {self.damping:.4g} N s/m: "
                f"{self.regime} (damping ratio {self.damping_ratio:.3g}); natural period "
                f"{self.natural_period:.3g} s; characteristic times: {times}; recommended dt "
                f"{self.recommended_dt:.3g} s; explicit integration unstable beyond dt = "
                f"{self.stability_limit:.3g} s")


def contact(mass: float, stiffness: float, damping: float | None = None, *,
            fraction: float = RECOMMENDED_FRACTION) -> ContactParams:
    """All of the above for one contact; damping None means critical damping."""
    m, k = _mass(mass), _stiffness(stiffness)
    d = _damping(damping, m, k)
    times = characteristic_times(m, k, d)
    return ContactParams(
        mass=m, stiffness=k, damping=d, critical_damping=critical_damping(m, k),
        damping_ratio=damping_ratio(m, k, d), regime=regime(m, k, d), natural_period=natural_period(m, k),
        natural_frequency=1.0 / natural_period(m, k), decay_time=decay_time(m, d), characteristic_times=times,
        smallest_time=min(times.values()), recommended_dt=recommended_dt(m, k, d, fraction=fraction),
        stability_limit=stability_limit(m, k, d))
