"""Work kept by content: a bake's distance grids and maps under a key of exactly their inputs.

A distance grid depends on its keyframe's mesh (vertices in world space: the mesh data and
its transform) and on the grid; a pair's maps on the pair's two distance grids, the grid
and motion grid, its feature pairs and the map options (`map_key`). Each is kept under a
digest of exactly those (`content_key`), so a bake, a re-bake or the live preview that
meets the same inputs takes the result instead of computing it again, and an input changed
anywhere misses only the results that read it: one Empty moved re-solves its pair's maps
alone, an Interpolation changed re-solves none (the bends are made from the maps).

The grids sit on a lattice in world space (`gridfit.lattice_grid`), so an edit within a
cell leaves the grids, and so the keys of everything else, as they were.

`WorkCache` holds the results pickled, in memory up to a bound (least recently used go
first) and, given a directory, on disk up to another (a file per key, written whole then
renamed, so two processes may share the directory). Results come back as copies: nothing
the bake changes reaches the cache.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import pathlib
import pickle
import threading
from collections import OrderedDict
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from ..base.grid import Grid

__all__ = ["WorkCache", "content_key", "grid_key", "array_digest", "MEMORY_BYTES", "DISK_BYTES"]

#: The memory a `WorkCache` holds by default: about 40 maps of the merge at 48 cells.
MEMORY_BYTES = 256 * 2**20
#: The disk a `WorkCache` with a directory holds by default.
DISK_BYTES = 2 * 2**30
#: The suffix of a cached result's file (`WorkCache.clear` removes only these).
_SUFFIX = ".kfi-work"


def array_digest(array: Any) -> str:
    """A digest of an array's dtype, shape and values."""
    a = np.ascontiguousarray(array)
    digest = hashlib.blake2b(f"{a.dtype.str}{a.shape}".encode(), digest_size=20)
    digest.update(a.tobytes())
    return digest.hexdigest()


def grid_key(grid: Grid | None) -> str:
    """What identifies a grid: its origin, spacing and shape, exactly (None: no grid)."""
    if grid is None:
        return "none"
    return repr((tuple(float(o) for o in grid.origin), float(grid.spacing), tuple(grid.shape)))


def content_key(kind: str, *parts: Any) -> str:
    """The key of a ``kind`` of result computed from ``parts`` (`_text`)."""
    digest = hashlib.blake2b(kind.encode(), digest_size=20)
    for part in parts:
        digest.update(_text(part).encode())
        digest.update(b"\0")
    return f"{kind}-{digest.hexdigest()}"


def _text(part: Any) -> str:
    """``part`` written out whole: an array by its values (`array_digest`: its repr elides
    them), a dataclass (options) field by field, a mapping or a sequence item by item, and
    anything else (numbers, names, None) by its repr, which is exact."""
    if isinstance(part, np.ndarray):
        return array_digest(part)
    if dataclasses.is_dataclass(part) and not isinstance(part, type):
        fields = (f"{f.name}={_text(getattr(part, f.name))}" for f in dataclasses.fields(part))
        return f"{type(part).__name__}({', '.join(fields)})"
    if isinstance(part, dict):
        return "{" + ", ".join(f"{_text(k)}: {_text(v)}" for k, v in part.items()) + "}"
    if isinstance(part, (list, tuple)):
        return "[" + ", ".join(_text(v) for v in part) + "]"
    return repr(part)


class WorkCache:
    """Results by key (`content_key`), bounded in memory and, with a ``directory``, on disk.

    Parameters
    ----------
    directory : path, optional
        Where results are also kept on disk (made when first needed): the directory of a
        user's cache or temporary files, never the add-on's own folder. None: memory only.
    memory_bytes, disk_bytes : int
        The bounds; the least recently used results go first past them (0 in memory: on
        disk only, for a process that bakes once).

    Attributes
    ----------
    counts : dict
        Per kind of key, ``hits`` and ``misses`` since the cache was made or cleared.
    """

    def __init__(self, directory: str | os.PathLike | None = None, *,
                 memory_bytes: int = MEMORY_BYTES, disk_bytes: int = DISK_BYTES) -> None:
        self.directory = None if directory is None else pathlib.Path(directory)
        self.memory_bytes, self.disk_bytes = int(memory_bytes), int(disk_bytes)
        self._memory = OrderedDict()  # key -> pickled result, oldest use first
        self._lock = threading.Lock()  # a chain's two threads may ask at once
        self.counts = {}

    def hits(self) -> dict[str, int]:
        """Per kind of key, the results taken from the cache so far."""
        with self._lock:
            return {kind: tally["hits"] for kind, tally in self.counts.items()}

    @property
    def memory_used(self) -> int:
        """Bytes of results held in memory."""
        return sum(len(b) for b in self._memory.values())

    def get(self, key: str) -> Any | None:
        """A copy of the result kept under ``key``, or None."""
        with self._lock:
            data = self._memory.get(key)
            if data is not None:
                self._memory.move_to_end(key)
            else:
                data = self._read(key)
                if data is not None:
                    self._keep(key, data)
            tally = self.counts.setdefault(key.split("-", 1)[0], {"hits": 0, "misses": 0})
            tally["hits" if data is not None else "misses"] += 1
        return None if data is None else pickle.loads(data)

    def put(self, key: str, value: Any) -> None:
        """Keep ``value`` under ``key`` (in memory, and on disk with a directory)."""
        data = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
        with self._lock:
            self._keep(key, data)
            self._write(key, data)

    def clear(self) -> int:
        """Drop every result, in memory and on disk; the bytes freed."""
        with self._lock:
            freed = self.memory_used
            self._memory.clear()
            for path in self._files():
                try:
                    freed += path.stat().st_size
                    path.unlink()
                except OSError:  # another process removed it first
                    pass
            self.counts = {}
        return freed

    def disk_used(self) -> int:
        """Bytes of results on disk (0 without a directory)."""
        total = 0
        for path in self._files():
            try:
                total += path.stat().st_size
            except OSError:
                pass
        return total

    def _keep(self, key, data):
        self._memory[key] = data
        self._memory.move_to_end(key)
        used = self.memory_used
        while used > self.memory_bytes:
            _, old = self._memory.popitem(last=False)
            used -= len(old)

    def _files(self):
        if self.directory is None or not self.directory.is_dir():
            return []
        return list(self.directory.glob(f"*{_SUFFIX}"))

    def _read(self, key):
        if self.directory is None:
            return None
        path = self.directory / f"{key}{_SUFFIX}"
        try:
            data = path.read_bytes()
            os.utime(path)  # its last use, for the bound
        except OSError:
            return None
        return data

    def _write(self, key, data):
        if self.directory is None or len(data) > self.disk_bytes:
            return
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            path = self.directory / f"{key}{_SUFFIX}"
            part = path.with_name(f"{path.name}.{os.getpid()}.part")
            part.write_bytes(data)
            os.replace(part, path)
        except OSError:  # a full or read-only disk: the result stays in memory only
            return
        self._trim_disk()

    def _trim_disk(self):
        """Remove the least recently used files until the directory is within its bound."""
        files = []
        for path in self._files():
            try:
                st = path.stat()
            except OSError:
                continue
            files.append((st.st_mtime, st.st_size, path))
        used = sum(f[1] for f in files)
        for _, size, path in sorted(files):
            if used <= self.disk_bytes:
                break
            try:
                path.unlink()
                used -= size
            except OSError:
                pass
