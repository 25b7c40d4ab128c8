"""Errors of the rendering and video side: each says what failed and what to do about it."""

VULKAN_HINT = (
    "Rendering uses Taichi's GGUI, which needs Vulkan. On a machine without a GPU driver, install "
    "Mesa's software driver (lavapipe) and the Vulkan loader: `sudo apt-get install mesa-vulkan-drivers "
    "libvulkan1` on Debian/Ubuntu (tools/setup.sh does this). `tai-coll info` checks it; the physics "
    "runs without Vulkan (`tai-coll run --no-render`).")


class RenderError(RuntimeError):
    """A frame could not be rendered or written."""


class VulkanUnavailableError(RenderError):
    """GGUI could not start because Vulkan (a loader and a driver) is missing."""


class VideoError(RenderError):
    """ffmpeg failed (its exit code and stderr are in the message) or a frame did not fit."""
