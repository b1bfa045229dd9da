"""Undo and redo of the viewer's style edits: a bounded stack of whole (immutable) Styles, so
undoing returns exactly the style before the edit, file values included."""

from __future__ import annotations

from collections import deque

LIMIT = 200  # steps kept


class History:
    def __init__(self, limit: int = LIMIT):
        self._undo: deque = deque(maxlen=limit)
        self._redo: list = []
        self._key = None  # the edit that may continue the last step (one drag = one step)

    def record(self, before, key=None, merge: bool = False) -> None:
        """``before`` is the state an edit replaced.  ``merge``: the edit continues the last one
        of the same ``key`` (a widget still being dragged): no new step."""
        if not (merge and key is not None and key == self._key and self._undo):
            self._undo.append(before)
        self._key = key
        self._redo.clear()

    def undo(self, current):
        """The state to go back to (``current`` becomes redoable), or None."""
        if not self._undo:
            return None
        self._key = None
        self._redo.append(current)
        return self._undo.pop()

    def redo(self, current):
        if not self._redo:
            return None
        self._key = None
        self._undo.append(current)
        return self._redo.pop()

    def clear(self) -> None:
        self._undo.clear()
        self._redo.clear()
        self._key = None

    @property
    def counts(self) -> tuple[int, int]:
        return len(self._undo), len(self._redo)
