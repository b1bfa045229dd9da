"""Traced lines cached by the inputs that determine their geometry.

The key hashes the field file's CONTENT (its bytes, in 1 MiB chunks, plus which snapshot of it;
for a ``.vtm`` multiblock file, the ``.vtu`` of the block it reads too),
the vector name, the seeds (the spec, and a seed file's content), the trace options, the flowkit
version and the source of the packages that make lines (``code_digest``: a checkout between
releases, or a fix, keeps its version but not its lines). The attribute set is not in the key:
an entry records which attributes it holds, so asking for another one can be answered without
tracing again when the attribute is a function of the vertices only (speed, velocity,
vorticity*, scalar fields, distance_to_seed): ``flowkit.sample`` adds it, with the same
``attributes.compute`` the integrator calls, on the very vertices it produced, stored in
float64. ``time`` and ``arc_length`` come from the integrator itself: asking for them re-traces.

Layout: ``DIR/<key>.h5`` (a lines file, float64 positions, lzf) and ``DIR/<key>.json`` (the inputs and
the attribute names), both written atomically; the JSON is written last, so an entry exists only
when both are complete.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

from ..fields.readers import SnapshotRef
from ..fields.readers.vtu import vtm_block
from ..integrate.attributes import ATTRIBUTES
from ..integrate.seeds import FILE_TYPES
from ..io.atomic import atomic_path
from ..io.lines_h5 import read_lines, write_lines
from ..lines import Lines

# attributes that need the integrator's own parameter: not derivable from stored vertices
FROM_INTEGRATOR = tuple(a for a, needs in ATTRIBUTES.items() if "params" in needs)
CHUNK = 1 << 20


def file_digest(path: str | Path) -> str:
    """blake2b-128 of the file's bytes, read in 1 MiB chunks."""
    h = hashlib.blake2b(digest_size=16)
    with open(path, "rb") as f:
        while block := f.read(CHUNK):
            h.update(block)
    return h.hexdigest()


# the packages whose source decides the traced lines and what they carry (readers, integrators,
# seeding, the lines file): not the renderer, the viewer or the command line
LINE_MAKERS = ("fields", "integrate", "seeding", "io", "lines.py")


@functools.cache
def code_digest() -> str:
    """blake2b-128 of flowkit's line-making source files (``LINE_MAKERS``, kernels' templates
    included), read once per process."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.blake2b(digest_size=16)
    for name in LINE_MAKERS:
        p = root / name
        files = [p] if p.is_file() else sorted(f for f in p.rglob("*")
                                               if f.suffix in (".py", ".j2") and f.is_file())
        for f in files:
            h.update(str(f.relative_to(root)).encode() + b"\0" + f.read_bytes())
    return h.hexdigest()


@dataclass(frozen=True)
class Entry:
    key: str
    path: Path
    point_attributes: tuple[str, ...]
    line_attributes: tuple[str, ...]


class LinesCache:
    """Cache directory of traced lines.  ``traced``/``hits``/``extended`` count what happened."""

    def __init__(self, directory: str | Path):
        self.dir = Path(directory)
        self._digests: dict[tuple, str] = {}  # per process: (path, size, mtime_ns) -> digest

    # -- keys -----------------------------------------------------------------------------------
    def _digest(self, path: Path) -> str:
        st = path.stat()
        k = (str(path.resolve()), st.st_size, st.st_mtime_ns)
        if k not in self._digests:
            self._digests[k] = file_digest(path)
        return self._digests[k]

    def inputs(self, plan, snap) -> dict:
        """Everything that determines the traced geometry of snapshot ``snap``."""
        from .. import __version__

        ref = snap.ref
        path, inner = (ref.path, ref.snapshot) if isinstance(ref, SnapshotRef) else (ref, None)
        seeds = plan.scene.seeds
        seed_in = {"spec": seeds, "prune": plan.scene.prune}
        if Path(seeds).suffix.lower() in FILE_TYPES and Path(seeds).is_file():
            seed_in["file_digest"] = self._digest(Path(seeds))
        opts = {k: v for k, v in dataclasses.asdict(plan.options).items()
                if k not in ("attributes", "progress", "budget", "memory")}  # (not the lines)
        field = {"digest": self._digest(Path(path)), "snapshot_in_file": inner,
                 "vector": plan.scene.field.vector}
        if Path(path).suffix.lower() == ".vtm":  # (names the .vtu it reads: that holds the data)
            field["block_digest"] = self._digest(vtm_block(path))
        field.update(plan.scene.field.load_options)  # (only those given: older keys stay valid)
        return {"field": field,
                "seeds": seed_in, "trace": opts, "flowkit": __version__, "code": code_digest()}

    @staticmethod
    def key(inputs: dict) -> str:
        text = json.dumps(inputs, sort_keys=True, default=list)
        return hashlib.sha256(text.encode()).hexdigest()[:32]

    # -- entries --------------------------------------------------------------------------------
    def get(self, key: str) -> Entry | None:
        meta, h5 = self.dir / f"{key}.json", self.dir / f"{key}.h5"
        if not (meta.is_file() and h5.is_file()):
            return None
        try:
            m = json.loads(meta.read_text())
            return Entry(key, h5, tuple(m["point_attributes"]), tuple(m["line_attributes"]))
        except (ValueError, KeyError, TypeError):
            return None  # a damaged entry is a miss; storing rewrites it

    def store(self, key: str, lines: Lines, inputs: dict) -> Entry:
        self.dir.mkdir(parents=True, exist_ok=True)
        # lzf: gzip would cost about as much as the trace itself; the cache is local scratch
        h5 = write_lines(lines, self.dir / f"{key}.h5", position_dtype="float64",
                         compression="lzf")
        meta = {"inputs": inputs, "point_attributes": sorted(lines.point_data),
                "line_attributes": sorted(lines.line_data)}
        with atomic_path(self.dir / f"{key}.json") as tmp:
            tmp.write_text(json.dumps(meta, indent=1, sort_keys=True, default=list))
        return Entry(key, h5, tuple(meta["point_attributes"]), tuple(meta["line_attributes"]))

    def read(self, entry: Entry, attributes=None) -> Lines:
        """The entry's lines with point ``attributes`` (None: all) and all per-line data."""
        names = entry.point_attributes if attributes is None else tuple(attributes)
        return read_lines(entry.path, attributes=[*names, *entry.line_attributes])

    # -- decisions ------------------------------------------------------------------------------
    @staticmethod
    def decide(entry: Entry | None, wanted) -> tuple[str, tuple[str, ...]]:
        """("hit" | "extend" | "retrace" | "trace", attributes missing from the entry)."""
        if entry is None:
            return "trace", tuple(wanted)
        missing = tuple(a for a in wanted if a not in entry.point_attributes)
        if not missing:
            return "hit", ()
        if any(a in FROM_INTEGRATOR for a in missing):
            return "retrace", missing
        return "extend", missing

    def status(self, plan, snap) -> str:
        """One line for --explain: what a run would do for ``snap``."""
        key = self.key(self.inputs(plan, snap))
        action, missing = self.decide(self.get(key), plan.attributes)
        text = {
            "hit": "hit: lines and attributes cached, no tracing",
            "extend": f"cached lines lack {', '.join(missing)}: computed on the cached vertices, "
                      "no re-trace",
            "retrace": f"cached lines lack {', '.join(missing)}, which only the integrator "
                       "gives: re-trace",
            "trace": "miss: trace",
        }[action]
        return f"{text} (key {key[:12]})"
