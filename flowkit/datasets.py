"""Built-in demo data: the OpenFOAM heated room (datasets/hotroom.h5, see datasets/README.md)."""

from __future__ import annotations

from pathlib import Path

from .fields import Field
from .fields.readers import load_field, load_series

_HERE = Path(__file__).resolve().parent


def bundled(source: str, hint: str) -> Path:
    """A file shipped with flowkit: ``source`` (relative to the source tree's root) in a checkout,
    or its name under flowkit/_data/ in an installed wheel (pyproject's force-include)."""
    src = _HERE.parent / source
    for p in (src, _HERE / "_data" / src.name):
        if p.is_file():
            return p
    raise FileNotFoundError(f"{src}: {hint}")


def hotroom_path() -> Path:
    """datasets/hotroom.h5: the built-in heated-room data."""
    return bundled("datasets/hotroom.h5", "built-in heated-room data not found; regenerate it "
                   "with `python datasets/make_hotroom.py`")


def hotroom_times() -> list[float]:
    """The snapshot times in seconds: 400, 800, 1200, 1600, 2000."""
    return [t for t, _ in load_series(hotroom_path())]


def hotroom(snapshot: int = -1, time: float | None = None) -> Field:
    """The heated room (10 m x 5 m x 10 m, 41 x 21 x 41 nodes) with U (m/s), T (K) and p.

    ``snapshot`` is a position (default -1: the last, t = 2000 s, closest to steady) or give
    ``time`` in seconds.
    """
    if time is not None:
        snapshot = None
    return load_field(hotroom_path(), snapshot=snapshot, time=time)
