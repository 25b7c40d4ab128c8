"""The first step of a substep with impulse pairs (docs/physics.md 5): every particle's
candidate state without contacts, and whether the neighbour lists kept from earlier substeps
still hold the candidates."""

import functools

import taichi as ti

from ...neighbors.verlet import SeenArgs, left_lists
from ...types import ACTIVE, ARRAY, ParticleArgs, Unused, vec3


@functools.cache
def predict_kernel(check: bool):
    """The prediction kernel, checking Verlet lists (seen: SeenArgs) or not (Unused)."""
    SeenType = SeenArgs if check else Unused

    @ti.kernel
    def predict(particles: ParticleArgs, gravity: vec3, dt: float, seen: SeenType, reach2: float, keep_x: ti.i32,
                # outputs
                x1: ARRAY, v1: ARRAY, stale: ARRAY, v_start: ARRAY, x_start: ARRAY):
        """The candidates x1 = x + dt v1, v1 = v + dt g (symplectic Euler; particles no longer
        simulated and sleeping ones keep their state), and (if check) in stale[0] whether the lists seen at
        seen.listed_at no longer hold: some candidate moved more than sqrt(reach2) from where
        the lists saw it, or its status changed since (neighbors/verlet.py). Also the state at
        the substep's start that the later passes read: v(t) into v_start, and x(t) into
        x_start if keep_x (in this launch rather than two copies of the arrays after it: a
        small scene's substep costs per launch)."""
        stale[0] = 0
        for i in range(particles.count):
            vi = particles.v[i]
            xi = particles.x[i]
            v_start[i] = vi
            if keep_x:
                x_start[i] = xi
            active = particles.flags[i] == ACTIVE
            if active and particles.rest[i] >= 0.0:  # (a sleeping particle stays: sleeping.py)
                vi = vi + dt * gravity
                xi = xi + dt * vi
            v1[i] = vi
            x1[i] = xi
            if ti.static(check):
                if left_lists(xi, active, seen.listed_at[i], reach2):
                    stale[0] = 1

    return predict
