"""Contact material of a collider (PHYSICS.md 2)."""

from __future__ import annotations

from dataclasses import dataclass

from . import validate


@dataclass(frozen=True)
class Material:
    """restitution e in [0, 1] (0: inelastic, 1: elastic); friction mu >= 0 (dry Coulomb,
    static and kinetic in one law); wet_friction D >= 0 in s/m (viscous: v_T scaled by
    max(0, 1 - D dv_N))."""

    restitution: float = 0.5
    friction: float = 0.3
    wet_friction: float = 0.0

    def __init__(self, *, restitution: float = 0.5, friction: float = 0.3, wet_friction: float = 0.0):
        object.__setattr__(self, "restitution", validate.real("restitution", restitution, low=0.0, high=1.0))
        object.__setattr__(self, "friction", validate.real("friction", friction, low=0.0))
        object.__setattr__(self, "wet_friction", validate.real("wet_friction", wet_friction, low=0.0))
