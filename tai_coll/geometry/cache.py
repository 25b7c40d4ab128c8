"""On-disk cache of baked signed-distance grids: content-hashed, versioned, written atomically.

A grid is stored under a key that hashes the format version, the mesh (vertex and face
arrays) and every bake parameter; a different mesh or parameter is a different file, so
entries never need invalidating. Files are written to a temporary name in the same folder
and moved into place with os.replace, so a reader never sees half a file, and an entry that
fails to load (truncated, another format version) is treated as a miss and baked again.

Folder: $TAI_COLL_CACHE_DIR if set, else $XDG_CACHE_HOME/tai_coll, else ~/.cache/tai_coll.
"""

import hashlib
import os
import tempfile
from pathlib import Path

import numpy as np

FORMAT_VERSION = 1
ENV_VAR = "TAI_COLL_CACHE_DIR"


def cache_dir() -> Path:
    """Where baked grids live (see the module docstring)."""
    if os.environ.get(ENV_VAR):
        return Path(os.environ[ENV_VAR]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "tai_coll"


def content_key(vertices: np.ndarray, faces: np.ndarray, **params) -> str:
    """SHA-256 of the format version, the mesh arrays and the bake parameters."""
    digest = hashlib.sha256()
    digest.update(f"tai_coll sdf grid v{FORMAT_VERSION}".encode())
    for array in (np.ascontiguousarray(vertices, dtype=np.float64), np.ascontiguousarray(faces, dtype=np.int64)):
        digest.update(str(array.shape).encode())
        digest.update(array.tobytes())
    for name in sorted(params):
        value = params[name]
        if isinstance(value, np.ndarray):
            value = value.tolist()
        digest.update(f"{name}={value!r};".encode())
    return digest.hexdigest()


def path_for(key: str) -> Path:
    return cache_dir() / f"sdf_{key[:40]}.npz"


def load(key: str):
    """The cached arrays for `key` as a dict, or None on a miss (absent, unreadable, other version)."""
    path = path_for(key)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            if int(data["format_version"]) != FORMAT_VERSION or str(data["key"]) != key:
                return None
            return {name: data[name] for name in data.files}
    except (OSError, ValueError, KeyError, EOFError):
        return None


def store(key: str, **arrays) -> Path:
    """Write the arrays for `key` atomically; returns the file's path."""
    path = path_for(key)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.stem, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as handle:
            np.savez(handle, format_version=np.int64(FORMAT_VERSION), key=np.str_(key), **arrays)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
