"""Rendered frames written behind the simulation: PNG files and video frames on a thread of
their own (docs/design-notes.md, "Frames written behind the simulation").

Writing a 1280 x 720 frame costs about half as much as rendering it (a PNG of zlib-compressed
rows, 4 ms, and 2.8 MB down ffmpeg's pipe, 7 ms, on the 2-core machine of docs/benchmarks.md).
zlib and the pipe release Python's lock while they work, so a thread of its own writes frame k
while the caller steps and renders frame k + 1, on the other core. At most `depth` frames wait,
so memory stays a few frames.

    writer = FrameWriter(video)                      # video: a VideoWriter, or None
    for k in range(frames):
        scene.step()
        writer.write(renderer.render(scene), png_path=folder / f"frame_{k:05d}.png")
    writer.close()                                   # waits for the last frames, closes the video

The frames are written in the order given. A failure in the thread (a full disk, ffmpeg
exiting) is raised by the next `write` or by `close`, and stops the writing: no later frame
is written and the video is aborted (no partial file). After the caller's own failure,
`abort()` writes the PNGs of the frames queued (so every frame rendered before the failure
has its file, as if written at once) and aborts the video.
"""

from __future__ import annotations

import queue
import threading
import time

import numpy as np

from .. import validate
from .png import check_frame, write_png
from .video import ClosedOnExit

_DONE = object()  # the queue's last item

#: Seconds `abort` waits for the frame being written before it stops ffmpeg under it.
ABORT_WAIT = 5.0


class FrameWriter(ClosedOnExit):
    """Writes (H, W, 3) uint8 frames in order, each to a PNG file and/or a VideoWriter, on one
    background thread. video: a VideoWriter or None; depth: frames that may wait (>= 1).
    waited: seconds the caller spent waiting on the thread (a full queue, `close`)."""

    def __init__(self, video=None, *, depth: int = 2):
        self.depth = validate.integer("depth", depth, low=1)
        self.video = video
        self.waited = 0.0
        self.frames_written = 0
        self._queue = queue.Queue(maxsize=self.depth)
        self._error = None
        self._stop = False
        self._thread = threading.Thread(target=self._run, name="tai_coll frame writer", daemon=True)
        self._thread.start()

    def write(self, image, png_path=None) -> None:
        """Queue a frame (the array is kept as given: do not change it afterwards), to be written
        as a PNG at png_path (if given) and into the video (if any). Raises what failed in the
        thread before, if anything did."""
        image = check_frame(image, "frame")
        self._raise()
        if self._thread is None:
            raise RuntimeError("this FrameWriter is closed")
        start = time.perf_counter()
        self._queue.put((np.ascontiguousarray(image), png_path))
        self.waited += time.perf_counter() - start

    def close(self):
        """Wait for every queued frame, then close the video (returns its path, or None). Raises
        what failed in the thread, if anything did (the video is then aborted)."""
        if self._thread is None:
            self._raise()
            return None
        start = time.perf_counter()
        self._queue.put(_DONE)
        self._thread.join()
        self._thread = None
        try:
            self._raise()
            return self.video.close() if self.video is not None else None
        finally:
            self.waited += time.perf_counter() - start

    def abort(self):
        """Stop (after a failure of the caller's): the frames queued are written as PNGs but not
        into the video, which is aborted (no file)."""
        self._stop = True
        if self._thread is not None:
            try:
                self._queue.put(_DONE, timeout=ABORT_WAIT)
                self._thread.join(timeout=ABORT_WAIT)
            except queue.Full:
                pass
            if self._thread.is_alive():  # stuck in a write that ffmpeg does not read: end ffmpeg
                if self.video is not None:
                    self.video.abort()
                while True:  # (what is left is dropped)
                    try:
                        self._queue.get_nowait()
                    except queue.Empty:
                        break
                self._queue.put(_DONE)
                self._thread.join()
            self._thread = None
        if self.video is not None:
            self.video.abort()

    def _raise(self):
        if self._error is not None:
            if self._thread is not None:
                self.abort()
            elif self.video is not None:
                self.video.abort()
            raise self._error

    def _run(self):
        while True:
            item = self._queue.get()
            if item is _DONE:
                return
            if self._error is not None:
                continue  # (drained: a failure stops the writing)
            image, png_path = item
            try:
                if png_path is not None:
                    write_png(png_path, image)
                if self.video is not None and not self._stop:
                    self.video.write(image)
                self.frames_written += 1
            except BaseException as error:  # raised in the caller's thread by write or close
                self._error = error
