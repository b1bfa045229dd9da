"""Test-session setup: no stale numba machine code (see flowkit/numba_cache.py)."""

from flowkit.numba_cache import drop_stale

drop_stale()
