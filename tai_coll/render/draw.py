"""A frame's particles and triangles declared to GGUI from NumPy vertex arrays
(docs/design-notes.md, "Rendering": "Vertices filled by NumPy").

GGUI (Taichi 1.7) draws from a host array of VERTEX_FLOATS float32 a vertex (position, normal,
texture coordinates, colour with alpha; a particle keeps its radius where a normal would go),
given to its scene by address. Taichi's Python wrappers (`Scene.particles`,
`Scene.mesh_instance`) fill that array with Taichi kernels: three launches a frame for
particles, and for meshes, which they take from fields, a copy over every place of the fields
and a read of the transforms. Those kernels were compiled in every process whose Taichi cache
was cold (about 0.45 s of the README demo's first frame) and launched in every frame (about
5 ms of a 6-particle frame). Here NumPy fills the arrays and they are handed to the scene as
the wrappers hand theirs, for the Taichi versions those wrappers were read in (1.7); elsewhere,
or with TAI_COLL_GGUI_DIRECT=0, the wrappers draw (from the Taichi fields of
window.MeshBuffers.fields).
"""

import numpy as np

from ..frontend_cache import may_patch

#: float32 values a vertex of GGUI's arrays: position 3, normal 3 (a particle's radius in the
#: first), texture coordinates 2, colour 4 (RGB, alpha)
VERTEX_FLOATS = 12
COLOR = slice(8, 11)  # (the RGB part of a vertex's colour)
_ALPHA = 11
_RADIUS = 3

_GREY = (0.5, 0.5, 0.5)  # (GGUI's colour argument, unused with colours per vertex)


def _field_info():
    """GGUI's description of an array for its scene (taichi.ui.utils.get_field_info), or None
    where this Taichi has none."""
    try:
        from taichi.ui.utils import get_field_info
    except ImportError:
        return None
    return get_field_info


def direct() -> bool:
    """Whether frames go to GGUI from NumPy arrays (see the module's notes): Taichi 1.7, and
    TAI_COLL_GGUI_DIRECT not 0."""
    return may_patch("TAI_COLL_GGUI_DIRECT") and _field_info() is not None


def vertices(positions: np.ndarray, normals: np.ndarray, colors: np.ndarray, out: np.ndarray | None = None):
    """GGUI's vertex array of n triangle corners (positions, normals, RGB colours, each (n, 3)):
    `out` reused when it holds n rows (else a new array); texture coordinates zero, alpha 1."""
    n = len(positions)
    if out is None or out.shape != (n, VERTEX_FLOATS):
        out = np.zeros((n, VERTEX_FLOATS), dtype=np.float32)
    out[:, 0:3] = positions
    out[:, 3:6] = normals
    out[:, COLOR] = colors
    out[:, _ALPHA] = 1.0
    return out


def particles(view, x: np.ndarray, radii: np.ndarray, colors: np.ndarray, held: np.ndarray | None = None):
    """Declare particles (centres x, radii, RGB colours; float32 arrays) in `view`, a GGUI
    scene; `held`: the array the last call returned (its rows are reused). Returns the vertex
    array to hand back next time (it must live until the frame is read: the caller keeps it)."""
    n = len(x)
    if not direct():
        view.particles(x, radius=float(radii[0]), per_vertex_radius=radii, per_vertex_color=colors)
        return held
    if held is None or len(held) < n:
        held = np.zeros((max(n, 2 * (0 if held is None else len(held))), VERTEX_FLOATS), dtype=np.float32)
    array = held[:n]  # (a contiguous view: rows of a C-ordered array)
    array[:, 0:3] = x
    array[:, _RADIUS] = radii
    array[:, COLOR] = colors
    array[:, _ALPHA] = 1.0
    # Taichi 1.7's SceneV2.particles, after its copies: (vertices, colour per vertex, radius per
    # vertex, colour, radius, index count, index offset)
    view.scene.particles(_field_info()(array), True, True, _GREY, float(radii[0]), n, 0)
    return held


def mesh(view, buffers, two_sided: bool = True):
    """Declare the triangles of `buffers` (window.MeshBuffers) in `view`, one instance with the
    identity transform (taichi 1.7's `mesh()` leaves its instance count uninitialised, and
    meshes drawn with it vanish from random frames)."""
    n = buffers.count
    if not direct():
        vertices_, normals, colors, transform = buffers.fields()
        view.mesh_instance(vertices_, normals=normals, per_vertex_color=colors, two_sided=two_sided,
                           vertex_count=n, transforms=transform)
        return
    info = _field_info()
    # Taichi 1.7's SceneV2.mesh_instance, after its copies: (vertices, colour per vertex,
    # indices, colour, two-sided, transforms, instance count and offset, index count and offset,
    # vertex count and offset, wireframe)
    view.scene.mesh_instance(info(buffers.vbo), True, info(None), _GREY, two_sided, info(buffers.transform),
                             1, 0, n, 0, n, 0, False)
