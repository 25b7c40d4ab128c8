"""Repulsion fields (docs/physics.md 4, seed 002): a collider that pushes particles away before
they touch it, with a strength that falls off with distance.

Attach one to a collider (`scene.add_collider(..., repulsion=tc.RepulsionField(...))`, read
by the `PenaltySolver`) or give one to `tc.ImpulseSolver(last_resort=...)`, where it replaces
the position push for particles found inside a collider.
"""

import math

import numpy as np
import taichi as ti

from .. import runtime, validate
from .penalty import FIELD_FORCE, FIELD_VELOCITY, PROFILE_EXPONENTIAL, PROFILE_LINEAR, repulsion_profile

KINDS = {"velocity": FIELD_VELOCITY, "force": FIELD_FORCE}
PROFILES = {"exponential": PROFILE_EXPONENTIAL, "linear": PROFILE_LINEAR}

#: The exponential profile's default range: where it has fallen to 0.1 % of its strength.
EXPONENTIAL_CUTOFF = 1e-3


class RepulsionField:
    """f(d) n, with d the gap (m) between the particle's surface and the collider's, n the
    collider's outward normal, f monotone decreasing to zero (seed 002).

    kind: "force" (f in N, added to the particle's forces) or "velocity" (f in m/s: the
        particle's velocity away from the surface, relative to the collider, is raised to
        at least f(d); a faster one keeps its speed).
    profile: "exponential", f(d) = strength exp(-decay d), decay in 1/m; or "linear",
        f(d) = max(0, strength - decay d), decay in (N or m/s) per m.
    strength: f(0) (> 0), in N or m/s by `kind`.
    decay: k of the profile (> 0). The linear profile also takes `range` instead.
    range: distance (m) beyond which the field is zero. Exponential: default where f has
        fallen to 0.1 % of its strength, ln(1000) / decay. Linear: strength / decay, or give
        `range` and not `decay` (then decay = strength / range).
    Inside a collider (d < 0) both profiles continue along their tangent at d = 0 (linear
    growth with the depth).
    Force fields are integrated explicitly: a field much stiffer than the contact,
    strength * decay / m > (2 / dt)^2, is unstable; velocity fields are not.
    """

    def __init__(self, *, kind: str = "force", profile: str = "exponential", strength: float,
                 decay: float | None = None, range: float | None = None):  # noqa: A002 (the seed's word)
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {tuple(KINDS)}; got {kind!r}")
        if profile not in PROFILES:
            raise ValueError(f"profile must be one of {tuple(PROFILES)}; got {profile!r}")
        self.kind = kind
        self.profile = profile
        self.strength = validate.real("strength", strength, low=0.0, low_open=True)
        decay = validate.real("decay", decay, low=0.0, low_open=True, allow_none=True)
        reach = validate.real("range", range, low=0.0, low_open=True, allow_none=True)
        if profile == "exponential":
            if decay is None:
                raise ValueError("decay (1/m) is required for profile='exponential'")
            if reach is None:
                reach = math.log(1.0 / EXPONENTIAL_CUTOFF) / decay
        else:
            if (decay is None) == (reach is None):
                raise ValueError("give exactly one of decay or range for profile='linear' "
                                 f"(got decay={decay!r}, range={reach!r})")
            if decay is None:
                decay = self.strength / reach
            reach = self.strength / decay if reach is None else reach
        self.decay = decay
        self.range = reach

    def packed(self) -> tuple:
        """(kind, profile, strength, decay, range) as kernels read them."""
        return (KINDS[self.kind], PROFILES[self.profile], self.strength, self.decay, self.range)

    def value(self, distances) -> np.ndarray:
        """f(d) at each gap d (m), computed by the kernels' own profile function."""
        d = np.ascontiguousarray(np.atleast_1d(np.asarray(distances, dtype=np.float64)),
                                 dtype=runtime.float_dtype())
        if d.ndim != 1 or not np.all(np.isfinite(d)):
            raise ValueError("distances must be a finite scalar or 1-D array")
        out = np.zeros_like(d)
        if len(d):
            _profile_kernel(d, PROFILES[self.profile], self.strength, self.decay, self.range, out)
        return out

    def __repr__(self):
        return (f"RepulsionField(kind={self.kind!r}, profile={self.profile!r}, strength={self.strength:g}, "
                f"decay={self.decay:g}, range={self.range:g})")


@ti.kernel
def _profile_kernel(d: ti.types.ndarray(), profile: ti.i32, strength: float, decay: float, reach: float,
                    # outputs
                    out: ti.types.ndarray()):
    for i in range(d.shape[0]):
        out[i] = repulsion_profile(d[i], profile, strength, decay, reach)


def pack(field: RepulsionField | None) -> tuple:
    """A field (or none) as the 5 numbers kernels read: kind, profile, strength, decay, range."""
    return field.packed() if field is not None else (0, 0, 0.0, 0.0, 0.0)
