"""Seeding that controls clutter: evenly spaced lines (``even``), seeds drawn from the data
(``data``: density, where), similarity pruning (``prune``), and ``trace_spec``, which traces any
``--seeds`` spec, the kinds that are seed points and the kind that grows lines alike."""

from __future__ import annotations

import numpy as np


def trace_spec(field, spec: str, options=None, *, backend="numba", empty="raise", **kw):
    """Lines of ``field`` from the seed spec ``spec`` (any ``--seeds`` form, ``even`` included);
    ``options``/``kw``/``empty`` as for ``flowkit.trace``."""
    # (not at the top: importing integrate.seeds runs this __init__ on its way to seeding.errors,
    # before integrate.seeds has defined these)
    from ..integrate.seeds import parse_even_spec, parse_seed_spec
    from ..integrate.trace import check_result, resolve_options, trace
    from .even import evenly_spaced

    opts = resolve_options(options, kw)
    even = parse_even_spec(spec)
    if even is None:
        return trace(field, parse_seed_spec(spec, field), opts, backend=backend, empty=empty)
    diag = float(np.linalg.norm(np.diff(field.grid.bounds, axis=1)))
    dsep, dtest = even.distances(diag)
    lines = evenly_spaced(field, dsep, dtest, opts, seed=even.seed, backend=backend)
    check_result(max(len(lines), 1), int((lines.n_vertices >= 2).sum()),
                 lines.line_data["reason"], empty)
    return lines


def needs_field(spec: str) -> bool:
    """True for specs whose seeds depend on the field's data (random, density, where, even)."""
    kind = str(spec).strip().partition(":")[0].lower()
    return kind in ("random", "density", "where", "even")

