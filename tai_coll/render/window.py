"""The one offscreen GGUI window of the process, and the triangles its meshes are drawn from.

GGUI renders with Vulkan. Nothing here runs until the first frame is rendered, so importing
tai_coll (and tai_coll.render) and running the physics never touch Vulkan. The window is
created hidden (`show_window=False`) and reused by every renderer; `show()` is never called:
`get_image_buffer_as_numpy()` renders the declared scene and clears it for the next frame.
A renderer asking for another size, or a Taichi restart (`tc.init` with other arguments),
replaces the window.
"""

from __future__ import annotations

import atexit
import os

import numpy as np
import taichi as ti

from .. import runtime
from . import draw
from .errors import VULKAN_HINT, VulkanUnavailableError

_window = None      # ti.ui.Window
_key = None         # (width, height, runtime generation) it was made for
_meshes = None      # MeshBuffers of the current runtime
_stray_ini = None   # imgui.ini that GGUI's Dear ImGui will write into the working folder, if not there before


def open_window(width: int, height: int):
    """The process's hidden GGUI window at width x height, created on first use.

    Raises VulkanUnavailableError, with what to install, when GGUI cannot start."""
    global _window, _key
    generation = runtime.ensure_init().generation
    key = (width, height, generation)
    if _window is not None and _key == key:
        return _window
    close_window()
    _note_ini()
    try:
        _window = ti.ui.Window("tai_coll", (width, height), show_window=False, vsync=False)
    except Exception as error:  # Taichi raises a bare RuntimeError (or GGUINotAvailableException)
        raise VulkanUnavailableError(f"could not start the offscreen renderer ({error}). {VULKAN_HINT}") from error
    _key = key
    return _window


def close_window():
    """Destroy the window (a later frame opens a new one)."""
    global _window, _key
    if _window is not None:
        try:
            _window.destroy()
        except Exception:  # already gone with a Taichi restart
            pass
    _window, _key = None, None
    _remove_stray_ini()


def _note_ini():
    """GGUI's Dear ImGui saves its window layout to ./imgui.ini when the window closes; an
    offscreen renderer has no layout to keep, so that file goes unless it was there first."""
    global _stray_ini
    path = os.path.abspath("imgui.ini")
    if _stray_ini is None and not os.path.exists(path):
        _stray_ini = path


def _remove_stray_ini():
    global _stray_ini
    if _stray_ini is not None:
        try:
            os.remove(_stray_ini)
        except OSError:
            pass
        _stray_ini = None


atexit.register(close_window)


class MeshBuffers:
    """Every collider triangle of a frame, as GGUI draws them: `vbo`, GGUI's vertex array of
    their corners (positions, normals, colours: draw.vertices), `count` corners, and
    `transform`, the one identity instance transform they are drawn with. NumPy arrays, handed
    to GGUI by draw.mesh; Taichi fields of them (`fields`) only where GGUI's own wrappers draw."""

    def __init__(self):
        self.count = 0
        self.owner = None
        self.vbo = np.zeros((0, draw.VERTEX_FLOATS), dtype=np.float32)
        self.transform = np.eye(4, dtype=np.float32)[None]
        self._uploads = 0  # uploads so far (fields() refills after one)
        self._fields = None  # (capacity, [vertices, normals, colours, transform], tree, uploads they hold)

    def upload(self, vertices: np.ndarray, normals: np.ndarray, colors: np.ndarray, owner=None):
        """Take n triangle corners; `owner` tags the content so a renderer can tell whether its
        geometry is still there."""
        self.vbo = draw.vertices(vertices, normals, colors, out=self.vbo)
        self.count = len(vertices)
        self.owner = owner
        self._uploads += 1

    def fields(self):
        """(vertices, normals, colours, transform) as f32 Taichi fields, for GGUI's own
        mesh_instance (draw.direct() False), filled from `vbo`. Allocated on first use and grown
        by doubling (a new field costs a kernel compile, so never per frame)."""
        n = self.count
        if self._fields is None or self._fields[0] < n:
            capacity = max(n, 2 * (0 if self._fields is None else self._fields[0]), 1 << 15)
            if self._fields is not None:
                self._fields[2].destroy()
            builder = ti.FieldsBuilder()
            made = [ti.Vector.field(3, ti.f32) for _ in range(3)] + [ti.Matrix.field(4, 4, ti.f32)]
            builder.dense(ti.i, capacity).place(*made[:3])
            builder.dense(ti.i, 1).place(made[3])
            tree = builder.finalize()
            made[3].from_numpy(self.transform)
            self._fields = (capacity, made, tree, None)
        capacity, made, tree, filled = self._fields
        if filled != self._uploads:
            staging = np.zeros((capacity, 3), dtype=np.float32)
            for field, columns in zip(made, (slice(0, 3), slice(3, 6), draw.COLOR)):
                staging[:n] = self.vbo[:n, columns]
                field.from_numpy(staging)
            self._fields = (capacity, made, tree, self._uploads)
        return tuple(made)


def mesh_buffers() -> MeshBuffers:
    """The process's MeshBuffers, made for the current Taichi runtime."""
    global _meshes
    generation = runtime.ensure_init().generation
    if _meshes is None or _meshes[0] != generation:
        _meshes = (generation, MeshBuffers())
    return _meshes[1]
