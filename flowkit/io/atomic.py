"""Atomic outputs: write to a temporary name in the target's directory, then rename.

A reader never sees a half-written file, and a failed write leaves an existing target untouched::

    with atomic_path("out.png") as tmp:     # tmp: ".out.<random>.tmp.png" beside out.png
        image.save(tmp)                     # on success tmp is renamed onto out.png;
                                            # on an exception tmp is removed, out.png unchanged

``AtomicPath`` is the same thing with explicit ``commit()`` / ``discard()`` for writers whose
lifetime is not one ``with`` block (e.g. ``flowkit.io.lines_h5.LinesWriter``).
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path


def check_output(target: str | os.PathLike) -> Path:
    """``target`` as a Path, or an error now, before any work, when it cannot be written: a
    directory, a directory that does not exist or is not writable."""
    p = Path(target)
    if p.is_dir():
        raise IsADirectoryError(f"{p}: is a directory, expected a file path")
    if not p.parent.is_dir():
        raise FileNotFoundError(f"{p}: directory {p.parent} does not exist")
    if not os.access(p.parent, os.W_OK):
        raise PermissionError(f"{p}: directory {p.parent} is not writable")
    return p


class AtomicPath:
    """A fresh temporary path beside ``target`` (same directory, so the rename is atomic).

    The temporary name keeps the target's suffix (libraries that pick a format from the
    extension still work) and starts with a dot (hidden from casual listings). The file is not
    created here: the caller's library creates it.
    """

    def __init__(self, target: str | os.PathLike):
        self.target = check_output(target)
        token = secrets.token_hex(6)
        self.tmp = self.target.with_name(f".{self.target.stem}.{token}.tmp{self.target.suffix}")
        self.done = False

    def commit(self) -> Path:
        """Flush the temporary file to disk and rename it onto the target."""
        if self.done:
            raise RuntimeError(f"{self.target}: atomic write already finished")
        self.done = True
        fd = os.open(self.tmp, os.O_RDONLY)
        try:
            os.fsync(fd)  # the data must be on disk before the rename makes it visible
        finally:
            os.close(fd)
        os.replace(self.tmp, self.target)
        return self.target

    def discard(self) -> None:
        """Remove the temporary file (if it was created); the target is left as it was."""
        self.done = True
        self.tmp.unlink(missing_ok=True)

    def __enter__(self) -> Path:
        return self.tmp

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.discard()


def atomic_path(target: str | os.PathLike) -> AtomicPath:
    """Context manager yielding a temporary path that becomes ``target`` on success."""
    return AtomicPath(target)
