"""Sleeping particles (docs/physics.md 5.3.1): a pile at rest is put to sleep, so that the few
passes of a substep cannot keep it trembling.

Each particle keeps an anchor, the position where it came to rest, and a rest time: how long
it has stayed within `sleep_drift` of its radius of the anchor while its contacts hold it (its
velocity is not what gravity alone would give it: it is supported, not flying). A particle that
leaves that ball, or flies, gets rest time zero and a new anchor where it is. After
`sleep_time` of rest it falls asleep: its velocity is set to zero and it does not move until it
is woken. The judgement is by positions, not by the stored velocity: a particle wedged in a
jammed pile can be given a velocity by its contacts every substep that its contacts take back
every substep (positions that cycle within a few micrometres while the velocity reads tens of
mm/s); it is still, and sleeping makes its velocity say so.

The Gauss-Seidel passes treat a sleeping particle as immovable (its awake partner takes the
whole change of a pair: `shares`), so particles resting on a sleeping layer rest on it as on a
floor and a pile comes to rest from the bottom up; two sleeping particles have nothing to
resolve.

A sleeping particle wakes
- when an awake particle within WAKE_REACH (r_i + r_j) of it is moving, its rest time zero (it
  left its ball in the last substep, or flies), faster than `wake_speed`: something comes at
  it, or what it rests on falls away (falling, it passes the wake speed while still that near);
- when a particle woken in this substep closes in on it faster than `wake_speed`, or one at
  rest (rest time above zero) faster than HIT_FACTOR * wake_speed (a hit it hands on):
  checked in every velocity pass with that pass's velocities, so that an impact goes on
  through the sleeping particles it reaches within the substep;
- when the host writes the particle state (set_positions, set_velocities, ...), gravity
  changes or a collider is added (colliders hold still while particles sleep: their passes
  leave a sleeping particle alone); and particles do not sleep while the scene has
  kinematic colliders (their motion may take a support away without touching the particle).
Slower, a particle at rest wakes nothing: the passes shift a particle wedged among sleeping
ones by a fraction of a millimetre now and then, at tens of mm/s, which would wake them all
again. So a slow push handed on through particles at rest meets a sleeping one as a wall, and
that part of an exchange does not conserve momentum (a row of 8 touching particles asleep,
hit at 1 m/s: about half of the momentum goes on; docs/design-notes.md).
A particle woken by a neighbour keeps its anchor with a rest time just above zero: it sleeps
again after sleep_time unless it moves.

ParticleStore.rest holds each particle's rest time (s), negative while asleep, and
ParticleStore.anchor its anchor.
"""

import taichi as ti

from ... import runtime
from ...types import ACTIVE, ARRAY, ParticleArgs, vec3

#: A sleep_time (s) that suits piles of millimetre to centimetre particles (sleeping is off
#: by default: see docs/physics.md 5.3.1).
SLEEP_TIME = 0.3
#: Default sleep_drift: how far (in its radius) a particle may stray from its anchor and still
#: count as at rest (a particle wedged in a pile trembles by about a percent of its radius).
SLEEP_DRIFT = 0.3
#: How near (in r_i + r_j) a moving awake particle wakes a sleeping one: a support that falls
#: away leaves its ball (SLEEP_DRIFT) well before it is that far.
WAKE_REACH = 1.1
#: Default wake_speed (m/s): a support falling away passes it within 5 ms of free fall.
WAKE_SPEED = 0.05
#: An awake particle at rest wakes a sleeping one it closes in on faster than this many times
#: wake_speed: a hit it hands on, well above the tens of mm/s the passes give a resting
#: particle (4 let 3 of the lattice pile's 10,648 stay awake at 2 s, 10 none).
HIT_FACTOR = 10.0
#: The rest time of a particle woken by a neighbour: above zero (it is no wake source itself
#: unless it moves), far below any sleep_time.
WOKEN = 1e-9
ASLEEP = -1.0  # the rest time of a sleeping particle
#: A contact acted on a particle when its velocity differs from v(t) + g dt by more than this
#: (relative, in m/s per m/s of that velocity, plus 1 m/s: above f32 round-off).
HELD = 1e-5


@ti.func
def is_asleep(particles: ti.template(), i):
    return particles.rest[i] < 0.0


@ti.func
def shares(mi, mj, asleep_i, asleep_j):
    """The parts of a pair's change of relative velocity (or of separation) that go to i and
    to j: by inverse mass, m_j / (m_i + m_j) and m_i / (m_i + m_j); a sleeping particle is
    immovable and takes none (its partner takes it all)."""
    inv_sum = 1.0 / (mi + mj)
    wi = ti.select(asleep_i, 0.0, ti.select(asleep_j, 1.0, mj * inv_sum))
    wj = ti.select(asleep_j, 0.0, ti.select(asleep_i, 1.0, mi * inv_sum))
    return wi, wj


@ti.func
def wakes(rest_awake, v_awake: vec3, toward: vec3, d2, reach, wake_speed):
    """Whether an awake particle with rest time rest_awake and velocity v_awake wakes a
    sleeping one whose centre is `toward` from its own (d2 = |toward|^2; reach: r_i + r_j):
    within WAKE_REACH * reach, it is moving (rest time zero) faster than wake_speed, or it
    closes in on the sleeping one faster than wake_speed if it was woken in this substep (rest
    time WOKEN), faster than HIT_FACTOR * wake_speed if it is at rest."""
    near = WAKE_REACH * reach
    closing = v_awake.dot(toward)
    fast = v_awake.norm_sqr() > wake_speed * wake_speed
    limit = ti.select(rest_awake <= WOKEN, wake_speed, HIT_FACTOR * wake_speed)
    return (d2 < near * near) & (((rest_awake == 0.0) & fast) |
                                 ((closing > 0.0) & (closing * closing > limit * limit * d2)))


@ti.func
def wake_pair(particles: ti.template(), i, j, asleep_i, asleep_j, v_i: vec3, v_j: vec3, d: vec3, d2, reach,
              wake_speed):
    """Wake the sleeping one of pair (i, j) if the other wakes it (see `wakes`; v_i, v_j: their
    velocities in the pass, d = x_i - x_j, d2 = |d|^2); returns the pair's sleep flags after."""
    if asleep_j != 0 and asleep_i == 0 and wakes(particles.rest[i], v_i, -d, d2, reach, wake_speed):
        particles.rest[j] = WOKEN
        asleep_j = 0
    elif asleep_i != 0 and asleep_j == 0 and wakes(particles.rest[j], v_j, d, d2, reach, wake_speed):
        particles.rest[i] = WOKEN
        asleep_i = 0
    return asleep_i, asleep_j


@ti.kernel
def update_rest(particles: ParticleArgs, x_start: ARRAY, v_start: ARRAY, gravity: vec3, dt: float,
                sleep_time: float, sleep_drift: float,
                # outputs
                awake: ARRAY, asleep: ARRAY):
    """At the end of a substep (the new state stored; x_start, v_start: x(t) and v(t), the
    latter changed by the elastic pass only): each awake particle's rest time and anchor, and
    those that have rested for sleep_time put to sleep. A particle that was resting before
    the substep and still is keeps a velocity no faster than its displacement over the
    substep: its stored velocity describes its motion (see the module's notes). awake[0],
    asleep[0]: whether any particle is awake, and asleep, at the end."""
    awake[0] = 0
    asleep[0] = 0
    for i in range(particles.count):
        if particles.flags[i] == ACTIVE:
            vi = particles.v[i]
            xi = particles.x[i]
            rest_i = particles.rest[i]
            if rest_i < 0.0:
                # (the colliders are static while particles sleep: what their pass did to a
                # sleeping particle is round-off)
                particles.v[i] = vec3(0.0)
                particles.x[i] = x_start[i]
                if asleep[0] == 0:
                    asleep[0] = 1  # (read first: one shared line, written once)
            else:
                free = v_start[i] + dt * gravity  # its velocity had no contact acted on it
                held = (vi - free).norm() > HELD * (free.norm() + 1.0)
                drift = sleep_drift * particles.radius[i]
                if held and (xi - particles.anchor[i]).norm_sqr() <= drift * drift:
                    if rest_i > 0.0:
                        speed = vi.norm()
                        moved = (xi - x_start[i]).norm() / dt
                        if speed > moved:
                            vi *= moved / speed
                    rest_i += dt
                    if rest_i >= sleep_time:
                        rest_i = ASLEEP
                        vi = vec3(0.0)
                    particles.v[i] = vi
                else:
                    rest_i = 0.0
                    particles.anchor[i] = xi
                particles.rest[i] = rest_i
                if rest_i >= 0.0 and awake[0] == 0:
                    awake[0] = 1  # (read first: one shared line, written once)
                elif rest_i < 0.0 and asleep[0] == 0:
                    asleep[0] = 1


def wake_key(particles, colliders) -> tuple:
    """What changes when something outside the substeps may wake a particle (see all_asleep):
    the store's edits, its count and its calls of wake_all, and the collider table's version."""
    return particles.edits, particles.count, particles.wakes, colliders.version


def all_asleep(awake, key_then, key_now) -> bool:
    """Whether every particle slept at the end of the last substep (update_rest's `awake`,
    written under key_then) and nothing woke one since (key_now is still key_then), so that the
    next substep would change nothing: a sleeping particle does not move, the passes skip a
    pair of two sleeping ones, the colliders' passes leave a sleeping particle alone (colliders
    hold still while particles sleep), and update_rest puts it back where the substep found it.
    What can wake one from outside changes the key (wake_key): the store's edits (host writes,
    added and removed particles, reordering), its calls of wake_all (gravity changed, sleeping
    turned off) and the collider table's version (a collider added). A read from the device."""
    return key_now == key_then and int(runtime.read_small(awake, 1)[0]) == 0
