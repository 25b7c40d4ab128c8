"""What every layer shares: particle status flags, event-counter slots, and the Taichi
argument packs that kernels take.

This is the bottom of the package: it imports Taichi and nothing of tai_coll but the runtime.

Argument packs (`ti.types.argpack`) name a kernel's arrays. A kernel takes, say,
`particles: ParticleArgs` and reads `particles.x[i]`, and hands the pack on to its @ti.func
helpers as a template argument. The scene's containers build their pack once and rebuild it
only when their arrays are reallocated or swapped (`ParticleStore.args`,
`ColliderTable.args`), since building one costs about as much as a launch.

Taichi turns the members of a kernel's packs into kernel arguments of the same names, so two
packs a kernel takes must not share an array member's name, and a kernel's own local
variables must not take one (a @ti.func's may): hence `neighbour_count`, not `count`, and
the springs' `held`, `stretch`, ....

Packs hold arrays and integers only. Array element types are left to the arrays passed in,
so one kernel serves f32 and f64 alike; a float member of a pack type, by contrast, would be
fixed to the precision Taichi had when this module was imported, before `tc.init()` chose
f32 or f64. Float settings therefore travel as named kernel parameters.
"""

import taichi as ti

from . import runtime

vec3 = ti.math.vec3
vec4 = ti.math.vec4
ivec3 = ti.math.ivec3
mat3 = ti.math.mat3

def host_vector(values) -> tuple:
    """A vector kernel argument made on the host: its entries as a tuple of floats. Taichi
    takes any sequence of numbers for a vector parameter, and building a ti.Vector on the
    host for each launch cost about as much as setting the launch's other arguments
    (docs/design-notes.md, "Launches")."""
    return tuple(map(float, values))


def new_ndarray(dtype, element_shape, shape):
    """A Taichi ndarray of `shape` items of `dtype` whose elements have `element_shape`:
    () a scalar, (n,) a vector, (n, m) a matrix (as an existing array's `element_shape`)."""
    element_shape = tuple(element_shape)
    if not element_shape:
        return ti.ndarray(dtype, shape=shape)
    if len(element_shape) == 1:
        return ti.Vector.ndarray(element_shape[0], dtype, shape=shape)
    return ti.Matrix.ndarray(element_shape[0], element_shape[1], dtype, shape=shape)


# ---------------------------------------------------------------------------- particle status
# ParticleStore.flags: what became of a particle.
ACTIVE = 0
LEFT_DOMAIN = 1  # left the scene's domain box: frozen where it left, no longer simulated
NON_FINITE = 2   # its state turned NaN/inf: frozen at its last finite state
REMOVED = 3      # its centre entered a sink: inactive, removed from the store at the end of the frame
STATUS_NAMES = ("active", "left_domain", "non_finite", "removed")

# ---------------------------------------------------------------------------- event counters
# Slots of the per-scene event counters (ParticleStore.stats), drained into Scene.stats().
STAT_FAILSAFE = 0
STAT_REPULSION = 1
STAT_NON_FINITE = 2
STAT_LEFT_DOMAIN = 3
STAT_NAMES = ("failsafe", "repulsion", "non_finite", "left_domain")

# ---------------------------------------------------------------------------- argument packs
#: An array of one element per item (scalar, vector or matrix, in the array's own dtype).
ARRAY = ti.types.ndarray(ndim=1)
#: An array of rows: items x slots (neighbour lists, springs).
TABLE = ti.types.ndarray(ndim=2)

#: The particle store (scene/particles.py): count, positions x (m), velocities v (m/s),
#: mass (kg), radius (m), status flags (ACTIVE, ...), overlap allowances (m), rest times (s;
#: negative: asleep) and rest anchors (m; docs/physics.md 5.3.1), and the event counters (STAT_...).
ParticleArgs = ti.types.argpack(count=ti.i32, x=ARRAY, v=ARRAY, mass=ARRAY, radius=ARRAY, flags=ARRAY,
                                allowance=ARRAY, rest=ARRAY, anchor=ARRAY, stats=ARRAY)

#: Angular velocities (rad/s) of spinning particles, beside the ParticleArgs.
SpinArgs = ti.types.argpack(w=ARRAY)

#: Array-backed shape data (grids, triangles, heights): per collider 8 integers (`ishape`)
#: and 8 floats (`fshape`) describing its block, and the float and integer pools the blocks
#: live in. Geometry functions take it (or a ColliderArgs, which has the same members) as
#: `g` with a collider index; analytic shapes ignore it. Host queries pass one collider's
#: rows in Taichi arrays of 8-vectors (geometry/queries.py).
ShapeArgs = ti.types.argpack(ishape=ARRAY, fshape=ARRAY, fpool=ARRAY, ipool=ARRAY)

#: The collider table (scene/colliders.py): count, kind, params (4 floats: shape parameters
#: and, in slot 3, a bounding-sphere radius), material (restitution, friction, wet friction),
#: the poses at the start (center0, rotation0) and end (center1, rotation1) of the substep,
#: the surface motion (velocity, angular_velocity) and the shape data of ShapeArgs.
#: Rigid bodies (bodies/coupling.py) are colliders too; per collider: `body` (the body's index,
#: -1 for a static or kinematic collider), `body_inv_mass` (1/kg) and `body_inv_inertia`
#: (world, 1/(kg m^2)) as each particle contact sees them (mass splitting, docs/physics.md 7.2),
#: `body_com` (its centre of mass at the substep's start), `body_up` (up, for a body resting on
#: what holds it, which particles lying on it meet as immovable; else zero); and the ledger of what particles
#: gave bodies this substep: two slots per particle (`ledger_body`: body or -1,
#: `ledger_impulse`: N s, `ledger_torque`: N m s about the body's centre of mass), and
#: `body_total` (2 rows per body, impulse and torque) for a third body touched at once;
#: `support` (per particle, shock.py's support levels) and `support_up` (one vector: up, or
#: zero while particles held by their supports do not stop bodies, docs/physics.md 7.2).
ColliderArgs = ti.types.argpack(count=ti.i32, kind=ARRAY, params=ARRAY, material=ARRAY, center0=ARRAY,
                                rotation0=ARRAY, center1=ARRAY, rotation1=ARRAY, velocity=ARRAY,
                                angular_velocity=ARRAY, ishape=ARRAY, fshape=ARRAY, fpool=ARRAY, ipool=ARRAY,
                                body=ARRAY, body_inv_mass=ARRAY, body_inv_inertia=ARRAY, body_com=ARRAY, body_up=ARRAY,
                                ledger_body=ARRAY, ledger_impulse=ARRAY, ledger_torque=ARRAY, body_total=ARRAY,
                                support=ARRAY, support_up=ARRAY)

#: A hash grid's counting sort (neighbors/hash_grid.py), for kernels that query it: the
#: table's bucket count and bits per axis, each bucket's first entry (`starts`), the particle
#: of each entry (`entries`) and a copy of positions and radii in entry order (`sorted_xr`).
#: (Its cell size travels beside it as the float `inv_cell`.)
GridArgs = ti.types.argpack(n_buckets=ti.i32, bits=ti.types.vector(3, ti.i32), starts=ARRAY, entries=ARRAY,
                            sorted_xr=ARRAY)

#: Neighbour lists: particle i's `neighbour_count[i]` neighbours lie in `neighbours` from
#: `first[i]` on (read them with neighbors.hash_grid.neighbour_of).
ListArgs = ti.types.argpack(neighbours=ARRAY, first=ARRAY, neighbour_count=ARRAY)

#: The pack a kernel gets for a feature it was compiled without (Taichi kernels have fixed
#: signatures; the feature's arrays are then not passed at all).
Unused = ti.types.argpack(unused=ti.i32)

_unused = {}


def unused() -> "Unused":
    """The Unused pack of the running Taichi runtime."""
    generation = runtime.ensure_init().generation
    if generation not in _unused:
        _unused.clear()
        _unused[generation] = Unused(unused=0)
    return _unused[generation]
