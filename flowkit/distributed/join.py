"""Join part files, in task order, into one lines file: the same lines, attributes and metadata a
single-process run writes (``trace_to_file``), streamed in batches of parts (at least
``BATCH_POINTS`` vertices per append, so small parts do not cost one small compressed write
each; memory stays at one batch).  The output appears atomically; the parts are removed only
once it has."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.lines_h5 import LinesWriter
from ..lines import Lines
from .tasks import read_part

BATCH_POINTS = 1 << 18


def join_parts(parts, out, *, snapshots=None, attrs=None, position_dtype="float32",
               remove=True) -> str:
    """Append the parts (paths, in order) to ``out``.  ``snapshots``: one snapshot index per part,
    stored as the line attribute ``snapshot`` (int32); ``attrs`` are added to the root metadata
    (e.g. ``snapshot_times``; a None value removes the parts' key).  Returns the output path (a
    str, cheap to send back)."""
    parts = [Path(p) for p in parts]
    missing = [str(p) for p in parts if not p.exists()]
    if missing:
        raise FileNotFoundError(f"{out}: {len(missing)} part file(s) missing, e.g. {missing[0]}")
    if not parts:
        raise ValueError(f"{out}: no parts to join")
    writer = None
    batch = []
    try:
        for i, p in enumerate(parts):
            lines = read_part(p)
            if snapshots is not None:
                lines.line_data["snapshot"] = np.full(len(lines), snapshots[i], np.int32)
            if writer is None:
                meta = {k: v for k, v in {**lines.attrs, **(attrs or {})}.items() if v is not None}
                writer = LinesWriter.like(lines, out, attrs=meta, position_dtype=position_dtype)
            batch.append(lines)
            if sum(b.n_points for b in batch) >= BATCH_POINTS or i == len(parts) - 1:
                writer.append(Lines.concatenate(batch) if len(batch) > 1 else batch[0])
                batch = []
        writer.close()
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    if remove:
        for p in parts:
            p.unlink(missing_ok=True)
    return str(out)
