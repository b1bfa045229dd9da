"""Poll a file for changes (once per frame: a stat, no thread, no dependency)."""

from __future__ import annotations

import os
from pathlib import Path


class FileWatch:
    """``changed()`` is True once after each change of the file's identity, size or mtime: an
    editor that saves in place or replaces the file (new inode) is seen either way."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self._sig = self._signature()

    def _signature(self):
        try:
            st = os.stat(self.path)
        except OSError:  # mid-replace or deleted: report when it is back
            return None
        return st.st_ino, st.st_size, st.st_mtime_ns

    def changed(self) -> bool:
        sig = self._signature()
        if sig is None or sig == self._sig:
            return False
        self._sig = sig
        return True
