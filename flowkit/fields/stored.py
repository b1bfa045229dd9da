"""Node arrays as a file stores them: read when first used, in the type the file holds.

A reader hands a Field a ``Stored`` array (shape, dtype, chunking and where it lives) instead of
reading it: opening a 13 GB snapshot then costs its metadata, ``flowkit info`` prints at once,
and a trace reads the vector and only the scalars its attributes use.  ``Stored.read()`` reads
the whole array in slabs along x into one array of its kept type, so that reading takes the
array's own bytes and a slab, and the memory it needs is checked before anything is allocated.

float32 and float64 arrays stay in the type the file stores (in native byte order): the
integrator reads float32 nodes and computes in float64, so lines from a float32 file are
bit-identical to those from its float64 copy (float32 -> float64 is exact) at half the memory.
Every other type (float16, integers) becomes float64.
"""

from __future__ import annotations

import contextlib
import os
import sys
from abc import ABC, abstractmethod

import numpy as np

KEPT = (np.dtype(np.float32), np.dtype(np.float64))
SLAB_BYTES = 64 << 20  # what one read of a slab may allocate beside the output


class FieldMemoryError(MemoryError):
    """An array that cannot be held in the memory this machine has free."""


def kept_dtype(dtype) -> np.dtype:
    """The type an array of ``dtype`` is held in: float32 or float64 as stored, else float64."""
    d = np.dtype(dtype).newbyteorder("=")
    return d if d in KEPT else np.dtype(np.float64)


def as_kept(a) -> np.ndarray:
    """``a`` as a C-contiguous array of its kept type (no copy when it is one already)."""
    a = np.asarray(a)
    return np.ascontiguousarray(a, dtype=kept_dtype(a.dtype))


def available_memory() -> int | None:
    """Bytes this machine can still allocate without swapping (Linux MemAvailable; psutil
    elsewhere when it is installed; None when neither says)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        import psutil
    except ImportError:
        return None
    return int(psutil.virtual_memory().available)


def fmt_bytes(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if abs(n) < 1000 or unit == "TB":
            return f"{n:.3g} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1000.0
    return f"{n} B"


def parse_bytes(text) -> int:
    """A size in bytes from a number or text such as "4GB", "512 MB", "3.5G", "2GiB"."""
    if isinstance(text, (int, np.integer)):
        return int(text)
    t = str(text).strip().upper().replace(" ", "").removesuffix("B")
    scale = 1
    for suffix, f in (("KI", 1 << 10), ("MI", 1 << 20), ("GI", 1 << 30), ("TI", 1 << 40),
                      ("K", 10**3), ("M", 10**6), ("G", 10**9), ("T", 10**12)):
        if t.endswith(suffix):
            t, scale = t[: -len(suffix)], f
            break
    try:
        value = float(t) * scale
    except ValueError:
        raise ValueError(f"not a size in bytes: {text!r} (e.g. 4GB, 512MB)") from None
    if not (value > 0 and np.isfinite(value)):
        raise ValueError(f"a size in bytes must be positive, got {text!r}")
    return int(value)


def check_memory(nbytes: int, what: str) -> None:
    """Raise FieldMemoryError, naming ``what`` and the sizes, when ``nbytes`` do not fit in
    the memory available now."""
    free = available_memory()
    if free is not None and nbytes > free:
        raise FieldMemoryError(
            f"{what} needs {fmt_bytes(nbytes)} of memory, {fmt_bytes(free)} available; "
            "free memory, or trace it (a trace reads a field brick by brick, --memory)"
        )


class Source(ABC):
    """Where a Stored array's values come from: ``fill_box(out, box)`` writes the nodes of
    ``box`` (three ``slice(start, stop)``, x, y, z) into ``out`` (their shape[, 3], the kept
    dtype).  Readers subclass it with picklable state (a path and a dataset name, not an open
    file), so that a Field can travel to another process and read there."""

    @abstractmethod
    def fill_box(self, out: np.ndarray, box: tuple) -> None:
        """Write the nodes of ``box`` into ``out``."""

    def fill(self, out: np.ndarray, i0: int, i1: int) -> None:
        """Write the nodes i0:i1 along x (a slab) into ``out``."""
        self.fill_box(out, (slice(i0, i1), slice(0, out.shape[1]), slice(0, out.shape[2])))

    def held(self):
        """A context in which a run of reads shares what each would open on its own (a file):
        opening costs as much as reading a brick."""
        return contextlib.nullcontext()


class InMemory(Source):
    """An array already in memory (or memory-mapped): a box is a copy of its part."""

    def __init__(self, array):
        self.array = array

    def fill_box(self, out, box):
        out[...] = self.array[box]


class Stacked(Source):
    """The three components of a vector, each a Stored scalar, as one (nx, ny, nz, 3) array."""

    def __init__(self, parts):
        self.parts = list(parts)

    def fill_box(self, out, box):
        tmp = np.empty(out.shape[:3], out.dtype)
        for c, p in enumerate(self.parts):
            p.source.fill_box(tmp, box)
            out[..., c] = tmp

    def held(self):
        stack = contextlib.ExitStack()
        for p in self.parts:
            stack.enter_context(p.source.held())
        return stack


class Flipped(Source):
    """Another source with the axes ``axes`` (of x, y, z: 0, 1, 2) in reverse order."""

    def __init__(self, inner: Source, shape, axes):
        self.inner, self.shape, self.axes = inner, tuple(shape[:3]), tuple(axes)

    def fill_box(self, out, box):
        box = tuple(slice(n - s.stop, n - s.start) if a in self.axes else s
                    for a, (s, n) in enumerate(zip(box, self.shape)))
        tmp = np.empty_like(out)
        self.inner.fill_box(tmp, box)
        out[...] = np.flip(tmp, axis=self.axes)

    def held(self):
        return self.inner.held()


class Stored:
    """A node array in a file, read on first use (``read``) or slab by slab (``slabs``).

    ``shape`` is (nx, ny, nz) or (nx, ny, nz, 3); ``dtype`` the type it is held in
    (``kept_dtype`` of ``stored``, the file's own); ``chunks`` the file's chunk shape, in
    the same index order, when it has one; ``where`` names the file and dataset for messages.
    """

    def __init__(self, shape, stored, source: Source, where: str, chunks=None):
        self.shape = tuple(int(n) for n in shape)
        self.stored = np.dtype(stored)
        self.dtype = kept_dtype(stored)
        self.source = source
        self.where = where
        self.chunks = None if chunks is None else tuple(int(c) for c in chunks)

    @property
    def ndim(self) -> int:
        return len(self.shape)

    @property
    def nbytes(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64)) * self.dtype.itemsize

    def slab_rows(self) -> int:
        """Nodes along x per slab: a chunk's depth where chunked, else SLAB_BYTES worth."""
        row = max(1, self.nbytes // max(1, self.shape[0]))
        rows = max(1, SLAB_BYTES // row)
        if self.chunks:
            c = self.chunks[0]
            rows = max(c, rows // c * c)
        return min(rows, self.shape[0])

    def _ranges(self):
        step, n = self.slab_rows(), self.shape[0]
        return ((i0, min(i0 + step, n)) for i0 in range(0, n, step))

    def slabs(self, progress=None):
        """Slabs along x, each read into an array of its own; ``progress(nbytes)`` after
        each."""
        for i0, i1 in self._ranges():
            out = np.empty((i1 - i0, *self.shape[1:]), self.dtype)
            self.source.fill(out, i0, i1)
            if progress is not None:
                progress(out.nbytes)
            yield out

    def read(self, progress=None) -> np.ndarray:
        """The whole array (C-contiguous, ``dtype``), its memory checked before it is taken."""
        check_memory(self.nbytes, f"{self.where}: reading {self.shape} {self.dtype}")
        out = np.empty(self.shape, self.dtype)
        with progress_bar(self.nbytes, f"reading {self.where}", progress) as done:
            for i0, i1 in self._ranges():
                self.source.fill(out[i0:i1], i0, i1)
                done(out[i0:i1].nbytes)
        return out

    def read_box(self, box) -> np.ndarray:
        """The nodes of ``box`` (three ``slice(start, stop)``), read alone."""
        box = tuple(slice(*s.indices(n)[:2]) for s, n in zip(box, self.shape))
        out = np.empty(tuple(s.stop - s.start for s in box) + self.shape[3:], self.dtype)
        self.source.fill_box(out, box)
        return out

    @staticmethod
    def of(a, where: str = "<memory>") -> Stored:
        """``a`` itself if it is Stored, else an in-memory (or memory-mapped) array seen as
        one, read a slab at a time."""
        return a if isinstance(a, Stored) else Stored(a.shape, a.dtype, InMemory(a), where)

    def flipped(self, axes) -> Stored:
        return Stored(self.shape, self.stored, Flipped(self.source, self.shape, axes),
                      self.where, None)

    @staticmethod
    def stacked(parts, where: str) -> Stored:
        """A vector from three Stored scalars of one shape."""
        stored = np.result_type(*(p.stored for p in parts))
        chunks = parts[0].chunks
        return Stored((*parts[0].shape, 3), stored, Stacked(parts), where,
                      None if chunks is None else (*chunks, 3))

    def __repr__(self):
        return f"Stored({self.where}, shape={self.shape}, dtype={self.dtype})"


# reads smaller than this show no progress bar
PROGRESS_BYTES = 256 << 20


class progress_bar:
    """A byte counter on stderr (tqdm) for work on PROGRESS_BYTES or more where stderr is a
    terminal; ``extra`` (a callable taking bytes) is called as well."""

    def __init__(self, total, label, extra=None):
        self.bar = None
        self.extra = extra
        if total >= PROGRESS_BYTES and sys.stderr.isatty() and not os.environ.get("CI"):
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=label, unit="B", unit_scale=True, leave=False)

    def __enter__(self):
        return self.update

    def update(self, n):
        if self.bar is not None:
            self.bar.update(n)
        if self.extra is not None:
            self.extra(n)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
