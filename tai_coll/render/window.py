"""The one offscreen GGUI window of the process, and the Taichi fields its meshes are drawn from.

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
    """f32 fields holding every collider triangle of a frame: positions, normals, colours,
    and the one identity instance transform they are drawn with.

    GGUI draws meshes from Taichi fields. They are allocated once, grown by doubling when a
    frame needs more (a new field costs a kernel compile, so never per frame)."""

    def __init__(self, capacity: int = 1 << 15):
        self.capacity = 0
        self._tree = None
        self._allocate(capacity)

    def _allocate(self, capacity: int):
        if self._tree is not None:
            self._tree.destroy()
        builder = ti.FieldsBuilder()
        self.vertices = ti.Vector.field(3, ti.f32)
        self.normals = ti.Vector.field(3, ti.f32)
        self.colors = ti.Vector.field(3, ti.f32)
        self.transform = ti.Matrix.field(4, 4, ti.f32)
        builder.dense(ti.i, capacity).place(self.vertices, self.normals, self.colors)
        builder.dense(ti.i, 1).place(self.transform)
        self._tree = builder.finalize()
        self.transform.from_numpy(np.eye(4, dtype=np.float32)[None])
        self._staging = np.zeros((capacity, 3), dtype=np.float32)
        self.capacity = capacity
        self.count = 0
        self.owner = None

    def upload(self, vertices: np.ndarray, normals: np.ndarray, colors: np.ndarray, owner=None):
        """Copy n triangle corners in; `owner` tags the content so a renderer can tell
        whether its geometry is still there."""
        n = len(vertices)
        if n > self.capacity:
            self._allocate(max(n, 2 * self.capacity))
        for field, values in ((self.vertices, vertices), (self.normals, normals), (self.colors, colors)):
            self._staging[:n] = values
            self._staging[n:] = 0.0
            field.from_numpy(self._staging)
        self.count = n
        self.owner = owner


def mesh_buffers() -> MeshBuffers:
    """The process's mesh fields, made for the current Taichi runtime."""
    global _meshes
    generation = runtime.ensure_init().generation
    if _meshes is None or _meshes[0] != generation:
        _meshes = (generation, MeshBuffers())
    return _meshes[1]
