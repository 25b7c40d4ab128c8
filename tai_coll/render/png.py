"""PNG files from (H, W, 3) uint8 frames: zlib from the standard library, written atomically."""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np

from .errors import RenderError


def check_frame(image, what: str = "image") -> np.ndarray:
    """An (H, W, 3) uint8 array, or a RenderError saying what it was instead."""
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.dtype != np.uint8 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise RenderError(f"{what} must be an (H, W, 3) uint8 array; got shape {arr.shape}, dtype {arr.dtype}")
    return arr


def encode_png(image, level: int = 3) -> bytes:
    """PNG bytes (8-bit RGB, no filter) of an (H, W, 3) uint8 image."""
    arr = np.ascontiguousarray(check_frame(image))
    h, w, _ = arr.shape
    rows = np.zeros((h, 1 + 3 * w), dtype=np.uint8)  # filter byte 0 ("none") then the row
    rows[:, 1:] = arr.reshape(h, 3 * w)

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows.tobytes(), level))
            + chunk(b"IEND", b""))


def write_png(path, image, level: int = 3) -> Path:
    """Write an (H, W, 3) uint8 image as a PNG; the file appears complete or not at all."""
    path = Path(path)
    data = encode_png(image, level)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except OSError as error:
        tmp.unlink(missing_ok=True)
        raise RenderError(f"could not write {path}: {error.strerror or error}") from error
    return path
