"""FrameWriter (tai_coll/render/behind.py): frames written as PNGs and into a video on a thread
of their own, in order, with the thread's failures raised in the caller's."""

import threading

import numpy as np
import pytest

from conftest import bad_codec_writer, bar_frames
from tai_coll.render import FrameWriter, RenderError, VideoError, VideoWriter


class HeldVideo:
    """A stand-in for a VideoWriter that keeps the frames it is given, each write waiting until
    `go` is set; `fail_at`: the frame whose write raises a VideoError."""

    def __init__(self, fail_at=None):
        self.go = threading.Event()
        self.entered = threading.Event()
        self.received, self.fail_at = [], fail_at
        self.closed = self.aborted = False

    def write(self, frame):
        self.entered.set()
        self.go.wait(timeout=60)
        if len(self.received) == self.fail_at:
            raise VideoError(f"ffmpeg failed at frame {self.fail_at}")
        self.received.append(frame.copy())

    def close(self):
        self.closed = True
        return "video.mp4"

    def abort(self):
        self.aborted = True


def test_pngs_and_video_hold_the_frames_in_order(tmp_path):
    imageio = pytest.importorskip("imageio")
    clip = bar_frames(7)
    with FrameWriter(VideoWriter(tmp_path / "clip.mp4", fps=24)) as writer:
        for k, f in enumerate(clip):
            writer.write(f, tmp_path / f"frame_{k}.png")
    assert writer.frames_written == 7 and writer.waited >= 0.0
    for k, f in enumerate(clip):
        assert np.array_equal(imageio.v3.imread(tmp_path / f"frame_{k}.png"), f)
    with imageio.get_reader(str(tmp_path / "clip.mp4"), format="FFMPEG") as reader:
        decoded = [d for d in reader]
    widths = [int((d[24, :, 0] > 120).sum()) for d in decoded]
    assert len(decoded) == 7
    assert np.all(np.abs(np.array(widths) - [(k + 1) * 64 // 7 for k in range(7)]) <= 2), widths
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["clip.mp4"] + [f"frame_{k}.png" for k in range(7)])


def test_the_caller_goes_on_while_a_frame_is_written():
    video = HeldVideo()
    writer = FrameWriter(video, depth=2)
    clip = bar_frames(3)
    for f in clip:  # the first is being written (held), two wait: no call blocks
        writer.write(f)
    assert video.entered.wait(timeout=60) and video.received == []
    video.go.set()
    assert writer.close() == "video.mp4" and video.closed and not video.aborted
    assert len(video.received) == 3 and all(np.array_equal(a, b) for a, b in zip(video.received, clip))


def test_a_failure_in_the_thread_is_raised_and_stops_the_writing(tmp_path):
    video = HeldVideo(fail_at=1)
    video.go.set()
    writer = FrameWriter(video, depth=1)
    with pytest.raises(VideoError, match="ffmpeg failed at frame 1"):
        for k, f in enumerate(bar_frames(30)):
            writer.write(f, tmp_path / f"frame_{k}.png")
        writer.close()
    assert len(video.received) == 1 and video.aborted and not video.closed
    written = sorted(p.name for p in tmp_path.iterdir())
    assert "frame_0.png" in written and len(written) <= 3  # (frames after the failure: not written)
    with pytest.raises(VideoError):  # it stays failed
        writer.close()


def test_ffmpeg_failing_leaves_no_video(tmp_path):
    with pytest.raises(VideoError, match=r"exit code [1-9]\d*[\s\S]*no_such_encoder"):
        with FrameWriter(bad_codec_writer()(tmp_path / "bad.mp4", fps=10)) as writer:
            for f in bar_frames(40):
                writer.write(f)
    assert not list(tmp_path.iterdir())


def test_a_png_that_cannot_be_written_names_its_path(tmp_path):
    writer = FrameWriter()
    writer.write(bar_frames(1)[0], tmp_path / "missing" / "a.png")
    with pytest.raises(RenderError, match=r"could not write .*missing"):
        writer.close()


def test_abort_writes_the_pngs_queued_and_no_video(tmp_path):
    video = HeldVideo()
    writer = FrameWriter(video, depth=4)
    for k, f in enumerate(bar_frames(4)):
        writer.write(f, tmp_path / f"frame_{k}.png")
    assert video.entered.wait(timeout=60)
    video.go.set()  # (the first frame's video write goes through; the rest go to PNGs only)
    writer.abort()
    assert video.aborted and not video.closed and len(video.received) <= 1
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"frame_{k}.png" for k in range(4)]
    with pytest.raises(RuntimeError, match="closed"):
        writer.write(bar_frames(1)[0])


def test_abort_leaves_no_video_file(tmp_path):
    writer = FrameWriter(VideoWriter(tmp_path / "clip.mp4", fps=10), depth=4)
    for f in bar_frames(6):
        writer.write(f)
    writer.abort()
    assert not list(tmp_path.iterdir())  # no video, no partial file


def test_abort_ends_a_write_that_ffmpeg_does_not_read(tmp_path, monkeypatch):
    from tai_coll.render import behind

    monkeypatch.setattr(behind, "ABORT_WAIT", 0.2)
    video = HeldVideo()  # its write never returns until abort ends it
    video.abort = lambda: (setattr(video, "aborted", True), video.go.set())
    writer = FrameWriter(video)
    writer.write(bar_frames(1)[0])
    assert video.entered.wait(timeout=60)
    writer.abort()
    assert video.aborted


def test_bad_input_is_refused_in_the_callers_thread():
    with pytest.raises(ValueError, match="depth"):
        FrameWriter(depth=0)
    writer = FrameWriter()
    with pytest.raises(RenderError, match=r"frame must be an \(H, W, 3\) uint8 array"):
        writer.write(np.zeros((4, 4, 3), dtype=np.float32))
    with pytest.raises(RenderError, match="uint8"):
        writer.write(np.zeros((4, 4), dtype=np.uint8))
    assert writer.close() is None
