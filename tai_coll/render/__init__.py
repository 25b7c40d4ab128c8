"""Seeing a simulation: offscreen frames with Taichi's GGUI, PNG files and videos.

    from tai_coll.render import Renderer, VideoWriter
    renderer = Renderer(width=1280, height=720)          # color_by="speed", camera=None: framed
    with VideoWriter("out/run.mp4", fps=60) as video:
        for _ in range(120):
            scene.step()
            video.write(renderer.render(scene))           # (H, W, 3) uint8

FrameWriter writes the frames (PNGs, a VideoWriter's) on a thread of its own, as `tai-coll run`
does, while the next frame is stepped and rendered.

Importing this package does not touch Vulkan; the first `render()` opens the process's one
hidden GGUI window, or raises VulkanUnavailableError saying what to install.
"""

from .behind import FrameWriter
from .camera import Camera
from .colormap import COLORMAPS, map_colors
from .errors import RenderError, VideoError, VulkanUnavailableError
from .png import encode_png, write_png
from .renderer import COLOR_ATTRIBUTES, Renderer
from .video import VideoWriter, ffmpeg_exe

__all__ = [
    "COLORMAPS", "COLOR_ATTRIBUTES", "Camera", "FrameWriter", "RenderError", "Renderer", "VideoError", "VideoWriter",
    "VulkanUnavailableError", "encode_png", "ffmpeg_exe", "map_colors", "write_png",
]
