"""Triangles for drawing colliders, in each collider's local frame.

Every drawable is a triangle soup (three vertices per triangle, none shared) with a normal
per corner: smooth across gentle edges, sharp across creases (a box's edges, a cylinder's
rims), so one shading path serves primitives, triangle meshes and height fields alike.

- Analytic shapes are built with trimesh.creation (icosphere, box, cylinder, capsule) and
  turned into their local frame (axis along local y, as tai_coll's colliders are).
- A plane is infinite; it is drawn as a checkered square of a given half-size around a
  point of the plane, so its tilt and motion stay visible.
- Other kinds (triangle meshes, height fields as terrain, signed-distance grids and
  implicit functions as their zero level set) are drawn from what the collider object
  exposes (`mesh_triangles`); a new kind can define `render_mesh()`. A kind with nothing
  usable is not drawable: `collider_triangles` returns None and the renderer logs a note.
"""


from dataclasses import dataclass

import numpy as np
import taichi as ti

from ..geometry.colliders import Box, Capsule, Cylinder, Plane, Sphere

CREASE_DEGREES = 35.0  # adjacent faces bent by more than this are shaded as an edge

# trimesh builds axial shapes along z; tai_coll's local axis is y.
_Z_TO_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@dataclass
class Tessellation:
    """A triangle soup in a local frame: vertices and normals (3T, 3); colors (3T, 3) for
    shapes with their own pattern (the plane's checker), else None."""

    vertices: np.ndarray
    normals: np.ndarray
    colors: np.ndarray | None = None

    @property
    def triangle_count(self) -> int:
        return len(self.vertices) // 3


def crease_normals(vertices, faces, crease_degrees: float = CREASE_DEGREES) -> Tessellation:
    """Unshare the vertices of an indexed mesh; each corner's normal averages (area
    weighted) the normals of the faces around its vertex that bend less than
    `crease_degrees` from its own face."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    tri = v[f]  # (F, 3, 3)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    twice_area = np.linalg.norm(cross, axis=1)
    face_n = cross / np.maximum(twice_area, 1e-300)[:, None]

    corner_vertex = f.ravel()
    corner_face = np.repeat(np.arange(len(f)), 3)
    order = np.argsort(corner_vertex, kind="stable")
    sorted_vertex = corner_vertex[order]
    starts = np.flatnonzero(np.r_[True, sorted_vertex[1:] != sorted_vertex[:-1]])
    counts = np.diff(np.r_[starts, len(order)])
    # Every ordered pair (a, b) of corners sharing a vertex: a's face gathers b's face normal.
    group_of = np.repeat(np.arange(len(starts)), counts)
    per_corner = counts[group_of]
    a = np.repeat(np.arange(len(order)), per_corner)
    block_start = np.repeat(np.cumsum(per_corner) - per_corner, per_corner)
    b = starts[group_of][np.repeat(np.arange(len(order)), per_corner)] + (np.arange(len(a)) - block_start)
    fa, fb = corner_face[order[a]], corner_face[order[b]]
    keep = np.einsum("ij,ij->i", face_n[fa], face_n[fb]) >= np.cos(np.radians(crease_degrees))
    acc = np.zeros((len(order), 3))
    np.add.at(acc, a[keep], face_n[fb[keep]] * twice_area[fb[keep], None])
    normals = np.empty((len(order), 3))
    normals[order] = acc
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.where(length > 1e-300, normals / np.maximum(length, 1e-300), face_n[corner_face])
    return Tessellation(tri.reshape(-1, 3), normals)


def _axial(mesh) -> Tessellation:
    return crease_normals(mesh.vertices @ _Z_TO_Y.T, mesh.faces)


def sphere(radius: float, subdivisions: int = 3) -> Tessellation:
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    tri = mesh.vertices[mesh.faces].reshape(-1, 3)
    return Tessellation(tri, tri / np.linalg.norm(tri, axis=1, keepdims=True))


def box(half_extents) -> Tessellation:
    import trimesh

    mesh = trimesh.creation.box(extents=2.0 * np.asarray(half_extents, dtype=np.float64))
    return crease_normals(mesh.vertices, mesh.faces)


def cylinder(radius: float, half_height: float, sections: int = 48) -> Tessellation:
    import trimesh

    return _axial(trimesh.creation.cylinder(radius=radius, height=2.0 * half_height, sections=sections))


def capsule(radius: float, half_height: float, count: int = 32) -> Tessellation:
    import trimesh

    return _axial(trimesh.creation.capsule(height=2.0 * half_height, radius=radius, count=[count, count]))


def plane(half_size: float, center=(0.0, 0.0), tiles: int = 16,
          colors=((0.80, 0.80, 0.82), (0.68, 0.69, 0.72))) -> Tessellation:
    """A checkered square in the local xz plane (local y is the plane's normal), of
    half-size `half_size` m around local (x, z) = `center`, `tiles` x `tiles` squares."""
    edges = np.linspace(-half_size, half_size, tiles + 1)
    i, k = np.meshgrid(np.arange(tiles), np.arange(tiles), indexing="ij")
    x0, x1 = edges[i.ravel()] + center[0], edges[i.ravel() + 1] + center[0]
    z0, z1 = edges[k.ravel()] + center[1], edges[k.ravel() + 1] + center[1]
    zero = np.zeros_like(x0)
    # two triangles per square, counter-clockwise seen from +y
    corners = [(x0, z0), (x0, z1), (x1, z1), (x0, z0), (x1, z1), (x1, z0)]
    verts = np.stack([np.column_stack([cx, zero, cz]) for cx, cz in corners], axis=1).reshape(-1, 3)
    normals = np.tile([0.0, 1.0, 0.0], (len(verts), 1))
    parity = ((i + k).ravel() % 2)[:, None]
    square_colors = np.where(parity == 0, colors[0], colors[1])
    return Tessellation(verts, normals, np.repeat(square_colors, 6, axis=0))


def height_field(heights, cell_size) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of terrain y = heights[i, j] over a grid centered on the local
    origin, cell (i, j) split into triangles (00, 11, 10) and (00, 01, 11) as the kernels
    split it, facing +y."""
    h = np.asarray(heights, dtype=np.float64)
    dx, dz = (cell_size, cell_size) if np.ndim(cell_size) == 0 else cell_size
    nx, nz = h.shape
    x = (np.arange(nx) - (nx - 1) / 2.0) * dx
    z = (np.arange(nz) - (nz - 1) / 2.0) * dz
    xx, zz = np.meshgrid(x, z, indexing="ij")
    vertices = np.column_stack([xx.ravel(), h.ravel(), zz.ravel()])
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(nz - 1), indexing="ij")
    v00 = (i * nz + j).ravel()
    v10, v01, v11 = v00 + nz, v00 + 1, v00 + nz + 1
    faces = np.concatenate([np.column_stack([v00, v11, v10]), np.column_stack([v00, v01, v11])])
    return vertices, faces


_CORNERS = np.array([[a, b, c] for a in (0, 1) for b in (0, 1) for c in (0, 1)], dtype=np.float64)
_EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if np.sum(np.abs(_CORNERS[a] - _CORNERS[b])) == 1]


def surface_nets(values, origin, spacing) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of the zero level set of a grid of signed values (negative inside)
    with nodes at origin + spacing * (i, j, k): one vertex per cell the surface crosses (the
    mean of its edges' crossings), one quad per grid edge it crosses, facing outward."""
    v = np.asarray(values, dtype=np.float64)
    n = np.array(v.shape)
    corners = np.stack([v[a:n[0] - 1 + a, b:n[1] - 1 + b, c:n[2] - 1 + c]
                        for a, b, c in _CORNERS.astype(int)], axis=-1)  # (cx, cy, cz, 8)
    inside = corners < 0
    active = inside.any(axis=-1) & ~inside.all(axis=-1)
    cells = np.argwhere(active)
    if len(cells) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    vals = corners[active]
    point_sum = np.zeros((len(cells), 3))
    count = np.zeros(len(cells))
    for a, b in _EDGES:
        crossing = (vals[:, a] < 0) != (vals[:, b] < 0)
        t = np.clip(vals[:, a] / np.where(crossing, vals[:, a] - vals[:, b], 1.0), 0.0, 1.0)
        point_sum += crossing[:, None] * (_CORNERS[a] + t[:, None] * (_CORNERS[b] - _CORNERS[a]))
        count += crossing
    vertices = np.asarray(origin, dtype=np.float64) + spacing * (cells + point_sum / count[:, None])
    index = np.full(active.shape, -1, dtype=np.int64)
    index[active] = np.arange(len(cells))

    faces = []
    for axis in range(3):
        u, w = (axis + 1) % 3, (axis + 2) % 3  # in-plane axes with u x w = axis
        lo = [slice(0, n[k] - 1) if k == axis else slice(1, n[k] - 1) for k in range(3)]
        hi = [slice(1, n[k]) if k == axis else slice(1, n[k] - 1) for k in range(3)]
        a_in, b_in = v[tuple(lo)] < 0, v[tuple(hi)] < 0
        nodes = np.argwhere(a_in != b_in)
        if len(nodes) == 0:
            continue
        outward_positive = a_in[tuple(nodes.T)]  # inside at the low end: the surface faces +axis
        nodes[:, u] += 1
        nodes[:, w] += 1  # back to grid indices of the edge's low node
        ring = []
        for du, dw in ((-1, -1), (0, -1), (0, 0), (-1, 0)):  # counter-clockwise seen from +axis
            c = nodes.copy()
            c[:, u] += du
            c[:, w] += dw
            ring.append(index[tuple(c.T)])
        ring = np.stack(ring, axis=1)
        ring[~outward_positive] = ring[~outward_positive][:, ::-1]
        faces += [ring[:, [0, 1, 2]], ring[:, [0, 2, 3]]]
    faces = np.concatenate(faces) if faces else np.zeros((0, 3), dtype=np.int64)
    return vertices, faces[np.all(faces >= 0, axis=1)]


def _sampled_taichi_function(shape, nodes_per_side: int = 48):
    """Values of an implicit's Taichi function on a grid over its bounds (local frame)."""
    lo, hi = shape.bounds
    h = float(np.max(hi - lo)) / (nodes_per_side - 1)
    dims = np.maximum(np.ceil((hi - lo) / h).astype(np.int64) + 1, 2)
    axes = [lo[a] + h * np.arange(dims[a]) for a in range(3)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    out = np.zeros(len(nodes), dtype=np.float32)
    _sample(shape.function, nodes.astype(np.float32), out)
    return out.reshape(tuple(dims)), lo, h


@ti.kernel
def _sample(f: ti.template(), points: ti.types.ndarray(dtype=ti.math.vec3, ndim=1), out: ti.types.ndarray()):
    for i in points:
        out[i] = f(points[i])


def _rest_pose_to_local(shape, points):
    """World points at the collider's rest pose to its local frame."""
    return (np.asarray(points, dtype=np.float64) - shape.center) @ shape.rotation


def mesh_triangles(shape):
    """(vertices, faces) in the local frame for collider kinds beyond the analytic ones,
    found by what the collider object exposes, first match wins:

    - `render_mesh()` -> (vertices, faces), local frame: the way for a new kind to say how
      it looks;
    - `heights` and `cell_size`: a height field centered on the local origin;
    - `vertices` and `faces`: a triangle mesh in the local frame;
    - `mesh` (a trimesh.Trimesh) with `mesh_center` (local = mesh - mesh_center), or
      without it, in world coordinates at the rest pose;
    - `values` (3-D signed grid), `origin` and `voxel_size`: the zero level set;
    - `function` (a Taichi function) and `bounds`: the zero level set of a sampled grid.

    Returns None when none applies."""
    if callable(getattr(shape, "render_mesh", None)):
        v, f = shape.render_mesh()
        return np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int64)
    if getattr(shape, "heights", None) is not None and getattr(shape, "cell_size", None) is not None:
        return height_field(shape.heights, shape.cell_size)
    if getattr(shape, "vertices", None) is not None and getattr(shape, "faces", None) is not None:
        return np.asarray(shape.vertices, dtype=np.float64), np.asarray(shape.faces, dtype=np.int64)
    mesh = getattr(shape, "mesh", None)
    if mesh is not None and hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        if getattr(shape, "mesh_center", None) is not None:
            local = np.asarray(mesh.vertices, dtype=np.float64) - shape.mesh_center
        else:
            local = _rest_pose_to_local(shape, mesh.vertices)
        return local, np.asarray(mesh.faces, dtype=np.int64)
    values = getattr(shape, "values", None)
    if values is not None and np.ndim(values) == 3 and getattr(shape, "origin", None) is not None:
        return surface_nets(values, shape.origin, shape.voxel_size)
    if getattr(shape, "taichi", False) and getattr(shape, "bounds", None) is not None:
        grid, lo, h = _sampled_taichi_function(shape)
        return surface_nets(grid, lo, h)
    return None


def collider_triangles(shape, *, plane_half_size: float = 1.0, plane_center=(0.0, 0.0)) -> Tessellation | None:
    """The local-frame tessellation of a collider, or None for a kind that cannot be drawn."""
    if isinstance(shape, Plane):
        return plane(plane_half_size, plane_center)
    if isinstance(shape, Sphere):
        return sphere(shape.radius)
    if isinstance(shape, Box):
        return box(shape.half_extents)
    if isinstance(shape, Cylinder):
        return cylinder(shape.radius, shape.half_height)
    if isinstance(shape, Capsule):
        return capsule(shape.radius, shape.half_height)
    found = mesh_triangles(shape)
    if found is None:
        return None
    vertices, faces = found
    if len(faces) == 0:
        return None
    tess = crease_normals(vertices, faces)
    if getattr(shape, "heights", None) is not None:
        tess.colors = terrain_colors(tess.vertices[:, 1])
    return tess


_TERRAIN = np.array([(0.42, 0.55, 0.36), (0.58, 0.62, 0.42), (0.62, 0.53, 0.42), (0.88, 0.88, 0.88)])


def terrain_colors(heights) -> np.ndarray:
    """Green lowlands, brown slopes, pale tops: colours by height over the terrain's range."""
    h = np.asarray(heights, dtype=np.float64)
    span = float(np.ptp(h))
    t = (h - h.min()) / span if span > 0 else np.zeros_like(h)
    knots = np.linspace(0.0, 1.0, len(_TERRAIN))
    return np.column_stack([np.interp(t, knots, _TERRAIN[:, c]) for c in range(3)])
