"""Video files streamed to the ffmpeg that imageio-ffmpeg ships (no system ffmpeg needed).

Frames go down a pipe one at a time, so a video of any length costs one frame of memory:

- mp4 (the default): H.264 (libx264), yuv420p so every player decodes it; odd sizes are
  padded by one pixel row or column (yuv420p needs even sizes).
- gif: scaled to a smaller width (`gif_width`, 480 px by default), one palette per frame
  (palettegen stats_mode=single), so ffmpeg need not hold the whole clip either.

ffmpeg writes to a hidden file next to the target, renamed into place once ffmpeg exits
with 0; otherwise VideoError shows its exit code and the end of its stderr.
"""

from __future__ import annotations

import os
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from .. import validate
from .errors import VideoError
from .png import check_frame

FORMATS = ("mp4", "gif")


def ffmpeg_exe() -> str:
    """Path of imageio-ffmpeg's ffmpeg binary (VideoError if it is missing)."""
    try:
        import imageio_ffmpeg
    except ImportError as error:
        raise VideoError("video export needs the imageio-ffmpeg package: pip install imageio-ffmpeg") from error
    try:
        return imageio_ffmpeg.get_ffmpeg_exe()
    except RuntimeError as error:
        raise VideoError(f"imageio-ffmpeg has no ffmpeg binary for this platform: {error}") from error


def ffmpeg_version() -> str:
    import imageio_ffmpeg

    return imageio_ffmpeg.get_ffmpeg_version()


class ClosedOnExit:
    """As a context manager: `close()` when the block ends, `abort()` when it raises."""

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:
            self.abort()
        return False


class VideoWriter(ClosedOnExit):
    """Stream (H, W, 3) uint8 frames into a video file.

        with VideoWriter("out/run.mp4", fps=60) as video:
            for _ in range(frames):
                scene.step()
                video.write(renderer.render(scene))

    path: the file; its suffix picks the format (.mp4 or .gif) unless `format` is given.
    fps: frames per second (> 0). crf: H.264 quality (0 lossless .. 51 worst; 18 to 23 look
    good). gif_width: width of a GIF in pixels (the height keeps the aspect ratio; never
    wider than the frames).
    """

    def __init__(self, path, *, fps: float = 30.0, format: str | None = None, crf: int = 20,
                 gif_width: int = 480):
        self.path = Path(path)
        self.fps = validate.real("fps", fps, low=0.0, low_open=True)
        fmt = (format or self.path.suffix.lstrip(".")).lower()
        if fmt not in FORMATS:
            raise ValueError(f"video format must be one of {FORMATS} (from the file suffix or format=); "
                             f"got {fmt or 'no suffix'!r} for {self.path}")
        self.format = fmt
        self.crf = validate.integer("crf", crf, low=0)
        if self.crf > 51:
            raise ValueError(f"crf must be <= 51; got {self.crf}")
        self.gif_width = validate.integer("gif_width", gif_width, low=2)
        self.frames_written = 0
        self.size = None  # (width, height) of the first frame
        self._proc = None
        self._stderr = None
        self._partial = None

    # ------------------------------------------------------------------ streaming
    def write(self, frame) -> None:
        """Append one frame; every frame must have the first frame's size."""
        frame = np.ascontiguousarray(check_frame(frame, "video frame"))
        h, w, _ = frame.shape
        if self._proc is None:
            self._start(w, h)
        elif (w, h) != self.size:
            self.abort()
            raise VideoError(f"video frame {self.frames_written} is {w}x{h}; "
                             f"the video is {self.size[0]}x{self.size[1]}")
        try:
            self._proc.stdin.write(frame.tobytes())
        except (BrokenPipeError, OSError):
            code = self._proc.wait()
            message = self._ffmpeg_failure(code)
            self.abort()
            raise VideoError(message) from None
        self.frames_written += 1

    def close(self) -> Path:
        """Finish the file: wait for ffmpeg, check its exit code, move the file into place."""
        if self._proc is None:
            if self.frames_written == 0 and self._partial is None:
                raise VideoError(f"no frames were written to {self.path}")
            return self.path
        proc, self._proc = self._proc, None
        try:
            proc.stdin.close()
        except OSError:
            pass
        code = proc.wait()
        if code != 0:
            message = self._ffmpeg_failure(code)
            self._cleanup()
            raise VideoError(message)
        os.replace(self._partial, self.path)
        self._partial = None
        self._cleanup()
        return self.path

    # ------------------------------------------------------------------ ffmpeg
    def command(self, width: int, height: int, output) -> list[str]:
        """The ffmpeg command line for frames of width x height (rgb24 on stdin)."""
        cmd = [ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-nostdin", "-y",
               "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-r", f"{self.fps:g}", "-i", "-",
               "-an"]
        if self.format == "mp4":
            cmd += ["-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-c:v", "libx264", "-preset", "medium",
                    "-crf", str(self.crf), "-pix_fmt", "yuv420p", "-movflags", "+faststart", "-f", "mp4"]
        else:
            gif_w = min(self.gif_width, width)
            cmd += ["-vf", f"scale={gif_w}:-2:flags=lanczos,split[a][b];[a]palettegen=stats_mode=single[p];"
                           "[b][p]paletteuse=new=1", "-loop", "0", "-f", "gif"]
        return cmd + [str(output)]

    def _start(self, width: int, height: int):
        if not self.path.parent.is_dir():
            raise VideoError(f"cannot write {self.path}: folder {self.path.parent} does not exist")
        self.size = (width, height)
        self._partial = self.path.with_name(f".{self.path.name}.{os.getpid()}.partial")
        self._stderr = tempfile.TemporaryFile()
        cmd = self.command(width, height, self._partial)
        try:
            self._proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=self._stderr)
        except OSError as error:
            self._cleanup()
            raise VideoError(f"could not start ffmpeg ({cmd[0]}): {error}") from error

    def _ffmpeg_failure(self, code: int) -> str:
        self._stderr.seek(0)
        err = self._stderr.read().decode(errors="replace").strip()
        tail = "\n".join(err.splitlines()[-15:]) or "(no message)"
        return f"ffmpeg failed writing {self.path} (exit code {code}):\n{tail}"

    def abort(self):
        """Stop ffmpeg and remove the partial file (after an error): no file is written."""
        if self._proc is not None:
            proc, self._proc = self._proc, None
            try:
                proc.stdin.close()
            except OSError:
                pass
            if proc.poll() is None:
                proc.kill()
            proc.wait()
        self._cleanup()

    def _cleanup(self):
        if self._partial is not None:
            self._partial.unlink(missing_ok=True)
            self._partial = None
        if self._stderr is not None:
            self._stderr.close()
            self._stderr = None
