"""How a frame is cut into substeps (docs/physics.md 3): a fixed number of substeps of a fixed
dt, or substeps="auto": each frame's count from the limits the scene has right then."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .. import validate

DEFAULT_DT = 1.0 / 600.0
DEFAULT_SUBSTEPS = 10
DEFAULT_FRAME_DT = 1.0 / 60.0
#: (a DEM pile at PenaltySolver(hertz=200)'s recommended dt takes about 220 a frame of 1/60 s)
DEFAULT_MAX_SUBSTEPS = 1000
#: substeps="auto": the most a particle may move in a substep, as a fraction of the smallest
#: radius. Half a radius keeps a pair's contact within one substep's reach of the impulse
#: passes and a DEM spring's overlap growing by less than a radius a substep.
DEFAULT_CFL = 0.5
# A run whose dt is beyond the stability limit is stopped as diverging once a particle is this
# many times faster than the starting speeds and gravity explain, plus this many m/s
# (collisions between particles redistribute speed but create none; moving colliders can at
# most double a particle's speed relative to them).
DIVERGED_FACTOR = 4.0
DIVERGED_SPEED = 1.0


@dataclass(frozen=True)
class SubstepChoice:
    """auto: substeps="auto"; frame_dt (s); max_substeps; cfl (a fraction of the smallest
    radius); dt_cap (s: the longest substep allowed); initial: (dt, substeps) before the first
    frame (with "auto": one substep of frame_dt until the first frame chooses)."""
    auto: bool
    frame_dt: float
    max_substeps: int
    cfl: float
    dt_cap: float
    initial: tuple

    @classmethod
    def build(cls, dt, substeps, frame_dt, max_substeps, cfl) -> "SubstepChoice":
        """Check Scene's arguments (dt, substeps, frame_dt, max_substeps, cfl: see Scene)."""
        if isinstance(substeps, str):
            if substeps != "auto":
                raise ValueError(f"substeps must be an integer >= 1 or 'auto'; got {substeps!r}")
            frame_dt = validate.real("frame_dt", DEFAULT_FRAME_DT if frame_dt is None else frame_dt, low=0.0,
                                     low_open=True)
            cap = frame_dt if dt is None else validate.real("dt", dt, low=0.0, low_open=True)
            max_substeps = validate.integer("max_substeps", DEFAULT_MAX_SUBSTEPS if max_substeps is None
                                            else max_substeps, low=1)
            cfl = validate.real("cfl", DEFAULT_CFL if cfl is None else cfl, low=0.0, low_open=True)
            return cls(True, frame_dt, max_substeps, cfl, min(cap, frame_dt), (frame_dt, 1))
        substeps = validate.integer("substeps", substeps, low=1)
        for name, value in (("max_substeps", max_substeps), ("cfl", cfl)):
            if value is not None:
                raise ValueError(f"{name} applies to substeps='auto' only; got substeps={substeps}")
        if frame_dt is not None:
            frame_dt = validate.real("frame_dt", frame_dt, low=0.0, low_open=True)
            if dt is not None and not math.isclose(dt * substeps, frame_dt, rel_tol=1e-9):
                raise ValueError(f"frame_dt: with a fixed number of substeps a frame is dt * substeps = "
                                 f"{dt * substeps:.6g} s; got frame_dt = {frame_dt:.6g} s (give one of dt and frame_dt)")
            dt = frame_dt / substeps
        dt = validate.real("dt", DEFAULT_DT if dt is None else dt, low=0.0, low_open=True)
        return cls(False, dt * substeps, substeps, 0.0, dt, (dt, substeps))

    def travel_dt(self, speed: float, radius: float, gravity: float) -> float:
        """The longest substep in which a particle at `speed` (m/s), accelerating at `gravity`
        (m/s^2), moves at most cfl * radius: speed dt + gravity dt^2 = cfl * radius (inf when
        nothing moves)."""
        travel = self.cfl * radius
        if travel <= 0.0:
            return math.inf
        root = speed + math.sqrt(speed * speed + 4.0 * gravity * travel)
        return math.inf if root == 0.0 else 2.0 * travel / root

    def choose(self, stable_dt: float | None, speed: float, radius: float, gravity: float) -> tuple:
        """A frame's substep count and what set it: the fewest equal substeps of frame_dt
        within every limit (stable_dt: the solver's recommended dt, None without one; speed:
        the fastest particle's; radius: the smallest), at most max_substeps."""
        limits = {"frame_dt": self.dt_cap, "cfl": self.travel_dt(speed, radius, gravity)}
        if stable_dt is not None:
            limits["stability"] = stable_dt
        limit = min(limits, key=limits.get)
        n = max(1, math.ceil(self.frame_dt / limits[limit] * (1.0 - 1e-12)))
        if n > self.max_substeps:
            return self.max_substeps, "max_substeps"
        return n, limit
