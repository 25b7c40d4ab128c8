"""Rendering and video: camera math against GGUI's, tessellations against the colliders' own
SDFs, frames against the simulation (a particle's projected center has its colour, its disc
its radius), collider meshes where they are, mp4/GIF files that decode.

Frames need Vulkan (tools/setup.sh installs Mesa's lavapipe). Without it these tests fail
with the renderer's install hint; set TAI_COLL_SKIP_RENDER_TESTS=1 to skip them instead.
"""

import importlib.util
import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tai_coll as tc
from conftest import bad_codec_writer, bar_frames
from tai_coll.render import (Camera, Renderer, RenderError, VideoError, VideoWriter, VulkanUnavailableError,
                             encode_png, map_colors, write_png)
from tai_coll.render import draw, tessellate, window

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted((ROOT / "scenes").glob("*.py"))
W, H = 160, 120


@pytest.fixture(scope="module")
def vulkan():
    """Skip only on request; otherwise a missing Vulkan fails with the install hint."""
    try:
        window.open_window(W, H)
    except VulkanUnavailableError as error:
        if os.environ.get("TAI_COLL_SKIP_RENDER_TESTS") == "1":
            pytest.skip(f"TAI_COLL_SKIP_RENDER_TESTS=1 and {error}")
        pytest.fail(str(error))


def flat_renderer(**kwargs):
    """Ambient light only (the point light is black): a surface shows exactly its colour."""
    return Renderer(width=W, height=H, ambient=1.0, lights=[((0.0, 0.0, 10.0), (0.0, 0.0, 0.0))], **kwargs)


def close_to(image, rgb, tol=6):
    return np.all(np.abs(image.astype(int) - np.round(np.asarray(rgb) * 255)) <= tol, axis=-1)


# ----------------------------------------------------------------------------- no Vulkan needed
def test_import_and_physics_do_not_load_vulkan():
    code = """
import numpy as np, tai_coll as tc, tai_coll.render
tc.init(arch="cpu")
s = tc.Scene()
s.add_collider(tc.Plane())
s.add_particles(positions=np.random.rand(100, 3) + [0, 0.1, 0])
s.step(2)
maps = open("/proc/self/maps").read()
print("vulkan loaded" if "libvulkan" in maps or "lvp" in maps else "no vulkan")
"""
    if not Path("/proc/self/maps").exists():
        pytest.skip("needs /proc/self/maps")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().endswith("no vulkan"), out.stdout


def test_camera_matches_ggui():
    import taichi as ti

    cam = Camera(position=(1.0, 2.0, 3.0), look_at=(0.0, 0.5, -0.2), up=(0.0, 1.0, 0.0), fov=38.0)
    ggui = ti.ui.Camera()
    ggui.position(*cam.position)
    ggui.lookat(*cam.look_at)
    ggui.up(*cam.up)
    ggui.fov(cam.fov)
    assert np.allclose(cam.view_matrix().T, np.array(ggui.get_view_matrix()), atol=1e-5)
    aspect = 16 / 9
    proj = np.array(ggui.get_projection_matrix(aspect))
    sx, sy = cam.focal(aspect)
    assert np.isclose(proj[0, 0], sx, rtol=1e-5) and np.isclose(proj[1, 1], sy, rtol=1e-5)
    assert proj[2, 3] == -1.0  # clip w = -z_view: depth along the view direction


def test_camera_projection_and_framing(rng):
    cam = Camera(position=(0.0, 0.0, 5.0), look_at=(0.0, 0.0, 0.0), fov=60.0)
    px, depth = cam.project([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], 200, 100)
    assert np.allclose(px[0], [100.0, 50.0]) and np.allclose(depth, 5.0)
    scale = 100 / (2 * 5 * np.tan(np.radians(30)))  # pixels per m at depth 5
    assert np.allclose(px[1], [100 + scale, 50]) and np.allclose(px[2], [100, 50 - scale])  # row 0 on top
    points = rng.uniform(-1, 1, (500, 3)) * [3.0, 0.5, 1.0] + [10.0, -2.0, 4.0]
    framed = Camera.framing(points.min(0), points.max(0), points=points, aspect=16 / 9, up=(0.0, 0.0, 1.0))
    px, depth = framed.project(points, 320, 180)
    assert np.all(depth > framed.near)
    assert np.all((px >= 0) & (px <= [320, 180]))
    assert np.ptp(px[:, 0]) > 0.6 * 320 or np.ptp(px[:, 1]) > 0.6 * 180  # and fills the frame
    with pytest.raises(ValueError, match="fov"):
        Camera(position=(0, 0, 1), fov=180)
    with pytest.raises(ValueError, match="parallel"):
        Camera(position=(0, 1, 0), look_at=(0, 0, 0), up=(0, 1, 0))


def test_colormaps_end_to_end():
    values = np.array([-1.0, 0.0, 0.5, 1.0, 2.0, np.nan])
    for name in ("viridis", "plasma", "turbo", "coolwarm", "gray"):
        c = map_colors(values, name, 0.0, 1.0)
        assert c.shape == (6, 3) and c.dtype == np.float32 and np.all((c >= 0) & (c <= 1))
        assert np.allclose(c[0], c[1]) and np.allclose(c[3], c[4])  # clipped at both ends
        assert np.allclose(c[5], c[2])  # NaN gets the middle
    assert np.allclose(map_colors([0.0, 1.0], "gray", 0, 1), [[0, 0, 0], [1, 1, 1]])
    with pytest.raises(ValueError, match="colormap"):
        map_colors([0.0], "jet", 0, 1)


@pytest.mark.parametrize("shape", [
    tc.Sphere(center=(0, 0, 0), radius=0.7),
    tc.Box(center=(0, 0, 0), half_extents=(0.3, 0.5, 0.2)),
    tc.Cylinder(center=(0, 0, 0), radius=0.4, half_height=0.6),
    tc.Capsule(center=(0, 0, 0), radius=0.25, half_height=0.5),
], ids=lambda s: type(s).__name__)
def test_tessellations_lie_on_the_collider(shape):
    """Vertices on the surface, normals outward: the local frame matches the SDF's (rest pose
    at the origin, so local = world)."""
    tess = tessellate.collider_triangles(shape)
    phi = shape.signed_distance(tess.vertices)
    assert np.max(np.abs(phi)) < 1e-6 * (1 + np.max(np.abs(tess.vertices)))
    assert np.allclose(np.linalg.norm(tess.normals, axis=1), 1.0)
    # corner normals point outward: along the SDF normal slightly off the surface
    outward = np.einsum("ij,ij->i", tess.normals, shape.normal(tess.vertices + 1e-3 * tess.normals))
    assert np.min(outward) > 0.5 and np.median(outward) > 0.95
    # triangles wind counter-clockwise seen from outside
    tri = tess.vertices.reshape(-1, 3, 3)
    face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(np.einsum("ij,ij->i", face, tess.normals[::3]) > 0)


def test_crease_normals_split_sharp_edges_only():
    import trimesh

    box = tessellate.crease_normals(*(lambda m: (m.vertices, m.faces))(trimesh.creation.box()))
    tri = box.vertices.reshape(-1, 3, 3)
    face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    face /= np.linalg.norm(face, axis=1, keepdims=True)
    assert np.allclose(box.normals, np.repeat(face, 3, axis=0))  # flat faces
    ball = trimesh.creation.icosphere(subdivisions=3)
    smooth = tessellate.crease_normals(ball.vertices, ball.faces)
    radial = smooth.vertices / np.linalg.norm(smooth.vertices, axis=1, keepdims=True)
    assert np.max(np.linalg.norm(smooth.normals - radial, axis=1)) < 0.02


def test_plane_is_a_checkered_square():
    tess = tessellate.collider_triangles(tc.Plane(), plane_half_size=2.0, plane_center=(1.0, -1.0))
    assert np.allclose(tess.vertices[:, 1], 0.0) and np.allclose(tess.normals, [0, 1, 0])
    assert np.allclose(tess.vertices.min(0), [-1, 0, -3]) and np.allclose(tess.vertices.max(0), [3, 0, 1])
    assert len(np.unique(tess.colors, axis=0)) == 2


def test_other_kinds_are_drawn_from_what_they_expose():
    """Kinds beyond the analytic ones: render_mesh(), vertices + faces (local), a trimesh
    with mesh_center (local = mesh - center) or without (world at the rest pose), a height
    grid, a signed-distance grid; a kind with none is not drawable."""
    import trimesh

    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3)
    center, rotation = np.array([1.0, 2.0, 3.0]), tc.rotation_matrix((0, 0, 1), 0.5)

    class Exposes:
        def __init__(self, **attrs):
            self.center, self.rotation = center, rotation
            self.__dict__.update(attrs)

    local = torus.vertices[torus.faces].reshape(-1, 3)
    world_at_rest = trimesh.Trimesh(torus.vertices @ rotation.T + center, torus.faces, process=False)
    shifted = trimesh.Trimesh(torus.vertices + [5.0, 0.0, 0.0], torus.faces, process=False)
    for shape in (Exposes(render_mesh=lambda: (torus.vertices, torus.faces)),
                  Exposes(vertices=torus.vertices, faces=torus.faces),
                  Exposes(mesh=shifted, mesh_center=np.array([5.0, 0.0, 0.0])),
                  Exposes(mesh=world_at_rest)):
        assert np.allclose(tessellate.collider_triangles(shape).vertices, local, atol=1e-9)

    heights = np.array([[0.0, 0.1, 0.0], [0.2, 0.3, 0.1]])
    terrain = tessellate.collider_triangles(Exposes(heights=heights, cell_size=(0.5, 0.25)))
    assert terrain.triangle_count == 2 * 1 * 2 and terrain.colors is not None
    assert np.allclose(sorted(set(terrain.vertices[:, 0])), [-0.25, 0.25])
    assert np.allclose(sorted(set(terrain.vertices[:, 2])), [-0.25, 0.0, 0.25])
    assert np.all(terrain.normals[:, 1] > 0)  # facing up

    axis = np.linspace(-1.0, 1.0, 33)
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij")
    grid = np.sqrt(x ** 2 + y ** 2 + z ** 2) - 0.6
    ball = tessellate.collider_triangles(Exposes(values=grid, origin=np.full(3, -1.0), voxel_size=axis[1] - axis[0]))
    radius = np.linalg.norm(ball.vertices, axis=1)
    assert np.max(np.abs(radius - 0.6)) < 0.01
    assert np.all(np.einsum("ij,ij->i", ball.normals, ball.vertices) > 0)  # outward

    assert tessellate.collider_triangles(Exposes()) is None


def test_mesh_collider_classes_tessellate_in_their_local_frame():
    """tai_coll's own mesh-like kinds (those this version has): each drawn surface lies on
    the collider's surface, placed by the collider's pose."""
    import trimesh

    rng = np.random.default_rng(1)
    makers = {
        "TriangleMesh": lambda: tc.TriangleMesh(trimesh.creation.torus(major_radius=0.4, minor_radius=0.1)),
        "HeightField": lambda: tc.HeightField(heights=0.1 * rng.random((6, 5)), cell_size=0.2, origin=(1, 0, 0)),
        "Implicit": lambda: tc.Implicit(lambda p: np.linalg.norm(p, axis=1) - 0.3, bounds=((-0.4,) * 3, (0.4,) * 3),
                                        center=(1.0, 0.0, 0.0)),
        "MeshSDF": lambda: tc.MeshSDF(trimesh.creation.icosphere(radius=0.3), resolution=24, cache=False,
                                      center=(0.0, 1.0, 0.0)),
    }
    present = [name for name in makers if hasattr(tc, name)]
    if not present:
        pytest.skip("no mesh-like colliders in this version")
    for name in present:
        shape = makers[name]()
        tess = tessellate.collider_triangles(shape)
        world = tess.vertices @ shape.rotation.T + shape.center
        assert np.max(np.abs(shape.signed_distance(world))) < 0.02, name


def test_png_encoding_round_trip(tmp_path, rng):
    iio = pytest.importorskip("imageio.v3")
    image = rng.integers(0, 256, (7, 11, 3), dtype=np.uint8)
    path = write_png(tmp_path / "a.png", image)
    assert np.array_equal(iio.imread(path), image)
    assert encode_png(image)[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(RenderError, match=r"\(H, W, 3\) uint8"):
        encode_png(image.astype(np.float32))
    with pytest.raises(RenderError, match="could not write"):
        write_png(tmp_path / "missing" / "a.png", image)


def test_renderer_arguments_are_checked():
    with pytest.raises(ValueError, match="width"):
        Renderer(width=0, height=10)
    with pytest.raises(ValueError, match="color_by"):
        Renderer(color_by="temperature")
    with pytest.raises(ValueError, match="colormap"):
        Renderer(colormap="rainbow")
    with pytest.raises(ValueError, match="color_range"):
        Renderer(color_range=(1.0, 0.0))
    with pytest.raises(ValueError, match="background"):
        Renderer(background=(2.0, 0.0, 0.0))
    with pytest.raises(TypeError, match="camera"):
        Renderer(camera=(0, 0, 1))


# ----------------------------------------------------------------------------- frames
def particle_scene():
    s = tc.Scene(gravity=(0.0, 0.0, 0.0))
    s.add_particles(positions=[[0.0, 0.0, 0.0], [0.5, 0.25, 0.0], [-0.45, -0.2, 0.3], [0.2, -0.3, -0.4]],
                    radius=np.array([0.1, 0.05, 0.08, 0.06]))
    return s


def test_frame_size_and_not_blank(vulkan):
    s = particle_scene()
    s.add_collider(tc.Box(center=(0.0, -0.6, 0.0), half_extents=(0.6, 0.05, 0.4)))
    for width, height in ((W, H), (97, 61)):
        image = Renderer(width=width, height=height).render(s)
        assert image.shape == (height, width, 3) and image.dtype == np.uint8
        assert image.std() > 5 and len(np.unique(image.reshape(-1, 3), axis=0)) > 20


def test_particles_are_where_the_simulation_put_them(vulkan):
    """Each particle's projected center shows its own colour, over a disc of its own radius;
    after a step they are drawn at the new positions."""
    s = particle_scene()
    s.set_velocities(np.tile([0.0, 3.0, 0.0], (4, 1)))
    index = np.arange(s.num_particles, dtype=float)
    r = flat_renderer(camera=Camera(position=(0.0, 0.0, 3.0)), color_by=lambda scene: index, colormap="turbo",
                      color_range=(0.0, 3.0))
    expected = map_colors(index, "turbo", 0.0, 3.0)
    for _ in range(2):
        image = r.render(s)
        pixels, depth = r.project(s.positions())
        for (col, row), color, radius, d in zip(pixels, expected, s.radii(), depth):
            assert close_to(image[int(row), int(col)], color), (image[int(row), int(col)], color)
            area = close_to(image, color).sum()
            disc = np.pi * (radius * r.camera.pixels_per_meter(d, H)) ** 2
            assert abs(area - disc) < 0.2 * disc + 6, (area, disc)
        s.step()  # 3 m/s x 1/60 s = 5 cm up: ~5 px at this scale


def test_colliders_are_drawn_where_they_are_this_frame(vulkan):
    """A still box and a sphere moving along x: each frame shows the sphere at its current
    center and the background where it was; frames of a still scene are identical."""
    s = tc.Scene(gravity=(0.0, 0.0, 0.0), dt=0.01, substeps=5)
    s.add_collider(tc.Box(center=(0.0, -0.5, 0.0), half_extents=(0.8, 0.1, 0.3)))
    moving = s.add_collider(tc.Sphere(center=(-0.5, 0.2, 0.0), radius=0.15), velocity=(10.0, 0.0, 0.0))
    r = flat_renderer(camera=Camera(position=(0.0, 0.0, 3.0)))
    first = r.render(s)
    start = moving.center.copy()
    s.step(2)  # 0.1 s at 10 m/s: 1 m along x
    second = r.render(s)
    for image, center in ((first, start), (second, moving.center)):
        col, row = r.project([center])[0][0]
        assert close_to(image[int(row), int(col)], r.moving_collider_color)
        col, row = r.project([[0.0, -0.5, 0.3]])[0][0]  # the box's front face
        assert close_to(image[int(row), int(col)], r.collider_color)
    col, row = r.project([start])[0][0]
    assert close_to(second[int(row), int(col)], r.background)

    still = tc.Scene()
    for k in range(8):
        still.add_collider(tc.Box(center=(k * 0.5, 0.0, 0.0), half_extents=(0.2, 0.1, 0.2),
                                  rotation=tc.rotation_matrix((0, 0, 1), 0.3)))
    still.add_particles(positions=[[0.0, 0.5, 0.0]], radius=0.02)
    r = Renderer(width=W, height=H)
    frames = [r.render(still) for _ in range(6)]
    assert all(np.array_equal(frames[0], f) for f in frames[1:])


def test_frames_drawn_from_numpy_match_ggui_wrappers(vulkan, monkeypatch):
    """Vertices filled by NumPy and handed to GGUI (draw.direct) give the frames Taichi's own
    wrappers give, to the byte: particles of several radii and colours, still and moving
    colliders, before and after a step and a growth of the particle count."""
    if not draw.direct():
        pytest.skip("GGUI is drawn through Taichi's wrappers here (not Taichi 1.7, or TAI_COLL_GGUI_DIRECT=0)")

    def frames():
        s = particle_scene()
        s.add_collider(tc.Box(center=(0.0, -0.6, 0.0), half_extents=(0.6, 0.05, 0.4),
                              rotation=tc.rotation_matrix((0, 1, 0), 0.4)))
        s.add_collider(tc.Sphere(center=(-0.4, 0.3, 0.0), radius=0.15), velocity=(2.0, 0.0, 0.0))
        s.add_collider(tc.Plane(point=(0.0, -0.7, 0.0), normal=(0.0, 1.0, 0.0)))
        r = Renderer(width=W, height=H, color_by="height")
        shots = [r.render(s)]
        s.step()
        shots.append(r.render(s))
        s.add_particles(positions=[[0.3, 0.4, 0.1], [-0.3, 0.2, 0.2]], radius=0.07)
        shots.append(r.render(s))
        return shots

    direct = frames()
    monkeypatch.setenv("TAI_COLL_GGUI_DIRECT", "0")
    assert not draw.direct()
    wrapped = frames()
    for a, b in zip(direct, wrapped):
        assert np.array_equal(a, b)
    assert len({a.tobytes() for a in direct}) == 3  # (the three frames differ)


def test_ggui_vertex_arrays_layout():
    """GGUI's vertex rows: position, normal (a particle's radius in its first place), texture
    coordinates, RGBA; the particles' array is reused while it holds them, grown when not."""
    rng = np.random.default_rng(3)
    p, n, c = (rng.random((5, 3)).astype(np.float32) for _ in range(3))
    v = draw.vertices(p, n, c)
    assert v.shape == (5, draw.VERTEX_FLOATS) and v.dtype == np.float32
    assert np.array_equal(v[:, 0:3], p) and np.array_equal(v[:, 3:6], n) and np.array_equal(v[:, 8:11], c)
    assert np.all(v[:, 6:8] == 0.0) and np.all(v[:, 11] == 1.0)
    assert draw.vertices(p, n, c, out=v) is v

    class Scene:
        def particles(self, info, *args):
            self.info, self.args = info, args

    class View:
        scene = Scene()

    if not draw.direct():
        pytest.skip("GGUI is drawn through Taichi's wrappers here")
    held = draw.particles(View, p, c[:, 0], n)
    assert held.shape == (5, draw.VERTEX_FLOATS)
    assert np.array_equal(held[:, 0:3], p) and np.array_equal(held[:, 3], c[:, 0])
    assert np.array_equal(held[:, 8:11], n) and np.all(held[:, 11] == 1.0)
    assert View.scene.info.shape == [5, draw.VERTEX_FLOATS] and View.scene.args[-2:] == (5, 0)
    assert draw.particles(View, p[:3], c[:3, 0], n[:3], held) is held  # reused
    assert View.scene.info.shape == [3, draw.VERTEX_FLOATS] and View.scene.args[-2:] == (3, 0)
    grown = draw.particles(View, np.vstack([p, p]), np.concatenate([c[:, 0]] * 2), np.vstack([n, n]), held)
    assert len(grown) >= 10 and View.scene.info.shape == [10, draw.VERTEX_FLOATS]


def test_one_window_reused(vulkan):
    s = particle_scene()
    Renderer(width=W, height=H).render(s)
    first = window.open_window(W, H)
    Renderer(width=W, height=H, color_by="height").render(s)
    assert window.open_window(W, H) is first
    assert Renderer(width=64, height=48).render(s).shape == (48, 64, 3)
    assert window.open_window(64, 48) is not first


class Unknown(tc.Collider):
    """A collider kind the renderer knows nothing about (never stepped: no kernel knows it)."""

    kind = 99

    def __init__(self):
        super().__init__(center=np.zeros(3), rotation=np.eye(3), params=(), bound=1.0)


def test_undrawable_collider_is_skipped_with_a_note(vulkan, caplog):
    s = particle_scene()
    s.add_collider(Unknown())
    s.add_collider(tc.Sphere(center=(0.0, -1.0, 0.0), radius=0.2))
    with caplog.at_level(logging.WARNING, logger="tai_coll.render"):
        image = Renderer(width=W, height=H).render(s)
    assert image.shape == (H, W, 3) and image.std() > 2
    assert any("cannot draw a Unknown collider" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_every_scene_script_renders(vulkan, path):
    """Each scene's first frame, with its render settings: every collider kind in the
    scenes is drawable (or skipped), and the frame is not blank."""
    spec = importlib.util.spec_from_file_location(f"render_scene_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    settings = module.render_settings() if hasattr(module, "render_settings") else {}
    settings.pop("width", None), settings.pop("height", None)
    image = Renderer(width=W, height=H, **settings).render(module.scene())
    assert image.shape == (H, W, 3) and image.std() > 2


def test_missing_vulkan_gives_the_install_hint(tmp_path):
    code = """
import tai_coll as tc
from tai_coll.render import Renderer, VulkanUnavailableError
tc.init(arch="cpu")
s = tc.Scene()
s.add_particles(positions=[[0, 0, 0]])
try:
    Renderer(width=32, height=24).render(s)
except VulkanUnavailableError as e:
    print("MESSAGE", e)
"""
    env = dict(os.environ, VK_ICD_FILENAMES=str(tmp_path / "no_driver.json"), VK_DRIVER_FILES=str(tmp_path / "no.json"))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "MESSAGE" in out.stdout and "mesa-vulkan-drivers libvulkan1" in out.stdout, out.stdout + out.stderr


# ----------------------------------------------------------------------------- video
def read_video(path):
    imageio = pytest.importorskip("imageio")
    with imageio.get_reader(str(path), format="FFMPEG") as reader:
        return [frame for frame in reader]


def test_mp4_decodes_to_the_frames_written(tmp_path):
    path = tmp_path / "clip.mp4"
    with VideoWriter(path, fps=24) as video:
        for f in bar_frames(7, 64, 48):
            video.write(f)
    decoded = read_video(path)
    assert len(decoded) == 7 and decoded[0].shape == (48, 64, 3)
    # the bar grows frame by frame: its width survives compression
    widths = [int((d[24, :, 0] > 120).sum()) for d in decoded]
    assert np.all(np.abs(np.array(widths) - [(k + 1) * 64 // 7 for k in range(7)]) <= 2), widths
    assert not list(tmp_path.glob(".*partial"))


def test_odd_sizes_are_padded_and_gif_is_smaller(tmp_path):
    with VideoWriter(tmp_path / "odd.mp4", fps=10) as video:
        for f in bar_frames(3, 65, 49):
            video.write(f)
    decoded = read_video(tmp_path / "odd.mp4")
    assert len(decoded) == 3 and decoded[0].shape == (50, 66, 3)
    with VideoWriter(tmp_path / "clip.gif", fps=10, gif_width=40) as video:
        for f in bar_frames(4, 80, 60):
            video.write(f)
    iio = pytest.importorskip("imageio.v3")
    gif = iio.imread(tmp_path / "clip.gif", index=None)
    assert gif.shape[0] == 4 and gif.shape[2] == 40


def test_ffmpeg_failure_shows_its_exit_code_and_message(tmp_path):
    path = tmp_path / "bad.mp4"
    with pytest.raises(VideoError, match=r"exit code [1-9]\d*[\s\S]*no_such_encoder"):
        with bad_codec_writer()(path, fps=10) as video:
            for f in bar_frames(40, 64, 48):
                video.write(f)
    assert not path.exists() and not list(tmp_path.iterdir())


def test_video_writer_refuses_bad_input(tmp_path):
    with pytest.raises(ValueError, match="format"):
        VideoWriter(tmp_path / "clip.avi")
    with pytest.raises(ValueError, match="fps"):
        VideoWriter(tmp_path / "clip.mp4", fps=0)
    with pytest.raises(VideoError, match="does not exist"):
        VideoWriter(tmp_path / "missing" / "clip.mp4").write(bar_frames(1, 8, 8)[0])
    video = VideoWriter(tmp_path / "clip.mp4")
    video.write(bar_frames(1, 16, 16)[0])
    with pytest.raises(VideoError, match="16x16"):
        video.write(bar_frames(1, 18, 16)[0])
    assert not (tmp_path / "clip.mp4").exists()
    with pytest.raises(VideoError, match="no frames"):
        VideoWriter(tmp_path / "empty.mp4").close()
