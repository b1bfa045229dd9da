"""Time series of snapshots: ParaView ``.series`` JSON, a glob of files, or a multi-snapshot
flowkit HDF5 file -> a list of (time, path or SnapshotRef) sorted by time.

Times come from the ``.series`` file, from the snapshot ``time`` attributes of a flowkit HDF5 file,
or, for a glob, from the last number (digits, optionally with a decimal part) in each file
name without its extension (``run_t0400.vtu`` -> 400,
``u.0012.vti`` -> 12).  When a name has no number or two names give the same number, the times
are instead 0, 1, 2, ... in name order (a note that the glob has no usable time stamps).
"""

from __future__ import annotations

import glob
import json
import re
from pathlib import Path
from typing import NamedTuple

from ._common import ReaderError

_NUMBER = re.compile(r"\d+(?:\.\d+)?")


class SnapshotRef(NamedTuple):
    """One snapshot inside a file that holds several; ``load_field(ref)`` loads it."""

    path: Path
    snapshot: int

    def __str__(self) -> str:  # (as the loaded Field's source names it)
        return f"{self.path}[snapshot {self.snapshot}]"


def read_series_json(path) -> list[tuple[float, Path]]:
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
        entries = doc["files"]
        out = [(float(e["time"]), path.parent / e["name"]) for e in entries]
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ReaderError(
            f"{path}: not a valid .series JSON file (truncated or corrupt): {e}"
        ) from None
    except (KeyError, TypeError, ValueError) as e:
        raise ReaderError(
            f'{path}: a .series file needs "files": [{{"name": ..., "time": ...}}, ...] '
            f"(problem: {type(e).__name__} {e})"
        ) from None
    if not out:
        raise ReaderError(f"{path}: the .series file lists no files")
    return sorted(out, key=lambda e: e[0])


def read_glob(pattern: str) -> list[tuple[float, Path]]:
    names = sorted(glob.glob(pattern))
    if not names:
        raise FileNotFoundError(f"{pattern}: no files match")
    nums = []
    for n in names:
        found = _NUMBER.findall(Path(n).stem)  # the name without its extension
        nums.append(float(found[-1]) if found else None)
    if None in nums or len(set(nums)) != len(nums):
        return [(float(i), Path(n)) for i, n in enumerate(names)]
    return sorted(zip(nums, map(Path, names)), key=lambda e: e[0])
