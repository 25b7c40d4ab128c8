"""Signed distance and outward normal of each analytic collider in its local frame.

PHYSICS.md 1. Every function takes a local point p and the collider's parameter vector and
returns (phi, n): phi < 0 inside, phi > 0 outside, |phi| the distance to the surface, n the
unit outward normal (the gradient of phi). Local frames: the plane is y = 0 with normal +y;
cylinder and capsule run along the local y axis. These are the only copies of the formulas:
the step kernels and the host-side `signed_distance` / `normal` both call them.
"""

import taichi as ti

from . import height_field, kinds, triangle_mesh
from .grid_sdf import grid_sdf
from .implicit_eval import implicit_sdf

vec3 = ti.math.vec3
vec4 = ti.math.vec4

TINY = 1e-12


@ti.func
def sign_nonzero(a):
    """+1 for a >= 0, -1 otherwise: a face direction that is defined on the midplane too."""
    return 1.0 if a >= 0.0 else -1.0


@ti.func
def plane_sdf(p: vec3):
    return p.y, vec3(0.0, 1.0, 0.0)


@ti.func
def sphere_sdf(p: vec3, radius):
    length = p.norm()
    n = vec3(0.0, 1.0, 0.0)  # at the center every direction is closest; pick +y
    if length > TINY:
        n = p / length
    return length - radius, n


@ti.func
def box_sdf(p: vec3, half: vec3):
    q = ti.abs(p) - half
    outside = ti.max(q, 0.0)
    out_len = outside.norm()
    phi = 0.0
    n = vec3(0.0, 0.0, 0.0)
    if out_len > 0.0:
        # Outside: the gradient points from the closest surface point to p.
        phi = out_len
        n = vec3(sign_nonzero(p.x), sign_nonzero(p.y), sign_nonzero(p.z)) * outside / out_len
    else:
        # Inside (or on a face): the nearest face is the one with the largest q.
        phi = ti.max(q.x, q.y, q.z)
        if q.x >= q.y and q.x >= q.z:
            n = vec3(sign_nonzero(p.x), 0.0, 0.0)
        elif q.y >= q.z:
            n = vec3(0.0, sign_nonzero(p.y), 0.0)
        else:
            n = vec3(0.0, 0.0, sign_nonzero(p.z))
    return phi, n


@ti.func
def cylinder_sdf(p: vec3, radius, half_height):
    """Capped cylinder about the local y axis."""
    rho = ti.sqrt(p.x * p.x + p.z * p.z)
    radial = vec3(1.0, 0.0, 0.0)
    if rho > TINY:
        radial = vec3(p.x / rho, 0.0, p.z / rho)
    axial = vec3(0.0, sign_nonzero(p.y), 0.0)
    dr = rho - radius
    dy = ti.abs(p.y) - half_height
    phi = 0.0
    n = radial
    if dr > 0.0 and dy > 0.0:
        # Beyond the rim: distance to the circular edge.
        phi = ti.sqrt(dr * dr + dy * dy)
        n = (dr * radial + dy * axial) / phi
    elif dr >= dy:
        phi = dr  # the side wall is the nearest (or the only crossed) surface
        n = radial
    else:
        phi = dy
        n = axial
    return phi, n


@ti.func
def capsule_sdf(p: vec3, radius, half_height):
    """Segment from (0, -h, 0) to (0, h, 0), swept by a sphere of `radius`."""
    q = vec3(p.x, p.y - ti.math.clamp(p.y, -half_height, half_height), p.z)
    length = q.norm()
    n = vec3(1.0, 0.0, 0.0)  # on the axis every radial direction is closest; pick +x
    if length > TINY:
        n = q / length
    return length - radius, n


@ti.func
def local_sdf(g: ti.template(), ci, kind: ti.i32, p: vec3, params: vec4):
    """Dispatch on the collider kind; `params` packs (radius | half extents, half height).
    Kinds backed by arrays (grids, triangles) read their block of the shape data `g`
    (scene.arrays.ShapeData) at collider index ci; analytic kinds ignore both."""
    phi = 0.0
    n = vec3(0.0, 1.0, 0.0)
    if ti.static(g.groups & kinds.GROUP_ANALYTIC):
        if kind == kinds.PLANE:
            phi, n = plane_sdf(p)
        elif kind == kinds.SPHERE:
            phi, n = sphere_sdf(p, params[0])
        elif kind == kinds.BOX:
            phi, n = box_sdf(p, vec3(params[0], params[1], params[2]))
        elif kind == kinds.CYLINDER:
            phi, n = cylinder_sdf(p, params[0], params[1])
        elif kind == kinds.CAPSULE:
            phi, n = capsule_sdf(p, params[0], params[1])
    if ti.static(g.groups & kinds.GROUP_TRIANGLES):
        if kind == kinds.TRIANGLE_MESH:
            phi, n = triangle_mesh.mesh_sdf(g, ci, p)
    if ti.static(g.groups & kinds.GROUP_HEIGHT):
        if kind == kinds.HEIGHT_FIELD:
            phi, n = height_field.field_sdf(g, ci, p)
    if ti.static(g.groups & kinds.GROUP_GRID):
        if kind == kinds.SDF_GRID:
            phi, n = grid_sdf(g, ci, p)
    if ti.static(g.groups & kinds.GROUP_IMPLICIT):
        phi, n = implicit_sdf(g, ci, kind, p)  # dispatches over the scene's implicit kinds
    return phi, n


@ti.func
def world_sdf(g: ti.template(), ci, kind: ti.i32, params: vec4, center: vec3, rotation: ti.math.mat3, x: vec3):
    """phi and the world-space normal at world point x for a collider posed at (center, R).

    Planes and spheres, the most common colliders, skip the two frame rotations: the plane's
    normal is the rotation's second column, and a sphere looks the same in every frame.
    """
    phi = 0.0
    n = vec3(0.0, 1.0, 0.0)
    if kind == kinds.PLANE:
        n = vec3(rotation[0, 1], rotation[1, 1], rotation[2, 1])
        phi = (x - center).dot(n)
    elif kind == kinds.SPHERE:
        phi, n = sphere_sdf(x - center, params[0])
    else:
        phi, n_local = local_sdf(g, ci, kind, rotation.transpose() @ (x - center), params)
        n = rotation @ n_local
    return phi, n
