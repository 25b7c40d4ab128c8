"""The kind dispatch: signed distance, normal and trajectory crossing of any collider kind
(docs/physics.md 1), one layer above the shapes' own queries.

Each function takes the shape data `g` (types.ShapeArgs, or the collider table's
types.ColliderArgs), the compile-time mask `groups` of collider kind groups the kernel
handles (geometry/kinds.py: every call site inlines the code of every kind compiled in, so
leaving out the groups a scene does not use keeps compile times short), the collider index
ci, its kind and its parameter vector.
"""

import taichi as ti

from . import analytic, kinds
from .grid_sdf import grid_crossing, grid_sdf
from .implicit_eval import implicit_crossing, implicit_sdf
from .marching import march_crossing
from .mesh_grid import mesh_crossing, mesh_sdf
from .terrain import field_crossing, field_sdf

vec3 = ti.math.vec3
vec4 = ti.math.vec4
mat3 = ti.math.mat3


@ti.func
def local_sdf(g: ti.template(), groups: ti.template(), ci, kind: ti.i32, p: vec3, params: vec4, reach=1e30):
    """phi and the outward normal at local point p; `params` packs (radius | half extents,
    half height). Kinds backed by arrays (grids, triangles) read their block of `g` at ci;
    analytic kinds ignore both."""
    phi = 0.0
    n = vec3(0.0, 1.0, 0.0)
    if ti.static(groups & kinds.GROUP_ANALYTIC):
        if kind == kinds.PLANE:
            phi, n = analytic.plane_sdf(p)
        elif kind == kinds.SPHERE:
            phi, n = analytic.sphere_sdf(p, params[0])
        elif kind == kinds.BOX:
            phi, n = analytic.box_sdf(p, vec3(params[0], params[1], params[2]))
        elif kind == kinds.CYLINDER:
            phi, n = analytic.cylinder_sdf(p, params[0], params[1])
        elif kind == kinds.CAPSULE:
            phi, n = analytic.capsule_sdf(p, params[0], params[1])
    if ti.static(groups & kinds.GROUP_TRIANGLES):
        if kind == kinds.TRIANGLE_MESH:
            phi, n = mesh_sdf(g, ci, p, reach)
    if ti.static(groups & kinds.GROUP_HEIGHT):
        if kind == kinds.HEIGHT_FIELD:
            phi, n = field_sdf(g, ci, p, reach)
    if ti.static(groups & kinds.GROUP_GRID):
        if kind == kinds.SDF_GRID:
            phi, n = grid_sdf(g, ci, p, reach)
    if ti.static(groups & kinds.GROUP_IMPLICIT):
        phi, n = implicit_sdf(g, groups, ci, kind, params, p, reach)  # over the scene's implicit kinds
    return phi, n


@ti.func
def world_plane(center: vec3, rotation: mat3, x: vec3):
    """A plane collider's phi and normal at world point x, without a frame rotation: the
    normal is the rotation's second column (the plane's local y), phi the height along it."""
    n = vec3(rotation[0, 1], rotation[1, 1], rotation[2, 1])
    return (x - center).dot(n), n


@ti.func
def world_sdf(g: ti.template(), groups: ti.template(), ci, kind: ti.i32, params: vec4, center: vec3, rotation: mat3,
              x: vec3, reach=1e30):
    """phi and the world-space normal at world point x for a collider posed at (center, R).

    Planes and spheres, the most common colliders, skip the two frame rotations: the plane's
    normal is the rotation's second column, and a sphere looks the same in every frame.
    """
    phi = 0.0
    n = vec3(0.0, 1.0, 0.0)
    if kind == kinds.PLANE:
        phi, n = world_plane(center, rotation, x)
    elif kind == kinds.SPHERE:
        phi, n = analytic.sphere_sdf(x - center, params[0])
    else:
        phi, n_local = local_sdf(g, groups, ci, kind, rotation.transpose() @ (x - center), params, reach)
        n = rotation @ n_local
    return phi, n


@ti.func
def local_crossing(g: ti.template(), groups: ti.template(), ci, kind: ti.i32, params: vec4, x0: vec3, x1: vec3, r):
    """First contact (hit, t, n) of a sphere of radius r moving x0 -> x1, in the local frame."""
    hit = False
    t = 1.0
    n = vec3(0.0, 1.0, 0.0)
    if ti.static(groups & kinds.GROUP_ANALYTIC):
        if kind == kinds.PLANE:
            hit, t, n = analytic.plane_crossing(x0, x1, r)
        elif kind == kinds.SPHERE:
            hit, t, n = analytic.sphere_crossing(x0, x1, params[0], r)
        elif kind == kinds.BOX or kind == kinds.CYLINDER or kind == kinds.CAPSULE:
            hit, t, n = march_crossing(analytic.convex_sdf, g, ci, kind, params, x0, x1, r, 1.0, True)
    if ti.static(groups & kinds.GROUP_TRIANGLES):
        if kind == kinds.TRIANGLE_MESH:
            hit, t, n = mesh_crossing(g, ci, x0, x1, r)
    if ti.static(groups & kinds.GROUP_HEIGHT):
        if kind == kinds.HEIGHT_FIELD:
            hit, t, n = field_crossing(g, ci, x0, x1, r)
    if ti.static(groups & kinds.GROUP_GRID):
        if kind == kinds.SDF_GRID:
            hit, t, n = grid_crossing(g, ci, x0, x1, r)  # non-convex: no slope early-out
    if ti.static(groups & kinds.GROUP_IMPLICIT):
        hit, t, n = implicit_crossing(g, groups, ci, kind, params, x0, x1, r)
    return hit, t, n


@ti.func
def world_crossing(g: ti.template(), groups: ti.template(), ci, kind: ti.i32, params: vec4, center: vec3,
                   rotation: mat3, x0: vec3, x1: vec3, r):
    """local_crossing for world points, the normal returned in world space. Planes, as in
    world_sdf, skip the rotations: their crossing needs the heights along the normal only."""
    hit = False
    t = 1.0
    n = vec3(0.0, 1.0, 0.0)
    if kind == kinds.PLANE:
        h0, n = world_plane(center, rotation, x0)
        h1, _n1 = world_plane(center, rotation, x1)
        hit, t = analytic.plane_heights_crossing(h0, h1, r)
    else:
        Rt = rotation.transpose()
        hit, t, n_local = local_crossing(g, groups, ci, kind, params, Rt @ (x0 - center), Rt @ (x1 - center), r)
        n = rotation @ n_local
    return hit, t, n
