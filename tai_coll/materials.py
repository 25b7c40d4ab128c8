"""Contact material of a collider (docs/physics.md 2 and 4)."""

from __future__ import annotations

from dataclasses import dataclass

from . import validate


@dataclass(frozen=True)
class Material:
    """restitution e in [0, 1] (0: inelastic, 1: elastic); friction mu >= 0 (dry Coulomb,
    static and kinetic in one law); wet_friction D >= 0 in s/m (viscous: v_T scaled by
    max(0, 1 - D dv_N)).

    static_friction mu_s >= 0: the penalty solver's static coefficient (a contact holds
    while the traction stays below mu_s |f_n|, then slides with the kinetic `friction`);
    None means the same as `friction`. The impulse solver's law has one coefficient for
    both and uses `friction` only; the penalty solver ignores `restitution` (its bounce
    comes from the damping) and reads `wet_friction` as the viscous force mu_v |f_n| v_t,
    the same physics as the impulse law's wet friction.

    rolling_friction mu_r >= 0 (dimensionless): rolling resistance, read by a
    `PenaltySolver(rotation=True)` only (the other solvers do not spin particles). A
    contact resists the rolling of a sphere of radius r with a torque of at most
    mu_r r |f_n| (a lever arm of mu_r r): a sphere on an incline of angle theta holds while
    tan(theta) <= mu_r (and <= static_friction), and rolls with
    a = 5/7 g (sin(theta) - mu_r cos(theta)) beyond.
    """

    restitution: float = 0.5
    friction: float = 0.3
    wet_friction: float = 0.0
    static_friction: float = 0.3
    rolling_friction: float = 0.0

    def __init__(self, *, restitution: float = 0.5, friction: float = 0.3, wet_friction: float = 0.0,
                 static_friction: float | None = None, rolling_friction: float = 0.0):
        object.__setattr__(self, "restitution", validate.real("restitution", restitution, low=0.0, high=1.0))
        object.__setattr__(self, "friction", validate.real("friction", friction, low=0.0))
        object.__setattr__(self, "wet_friction", validate.real("wet_friction", wet_friction, low=0.0))
        static = validate.real("static_friction", static_friction, low=0.0, allow_none=True)
        object.__setattr__(self, "static_friction", self.friction if static is None else static)
        object.__setattr__(self, "rolling_friction", validate.real("rolling_friction", rolling_friction, low=0.0))
