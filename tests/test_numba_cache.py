"""drop_stale removes numba caches that a newer source (own package or a shared one) outdates."""

import os

from flowkit.numba_cache import drop_stale


def _tree(tmp_path, cache_time, src_time, fields_time):
    for pkg, t in (("integrate", src_time), ("fields", fields_time), ("render", 100.0)):
        (tmp_path / pkg / "__pycache__").mkdir(parents=True)
        src = tmp_path / pkg / "m.py"
        src.write_text("")
        os.utime(src, (t, t))
        for name in ("m.f-1.py311.nbi", "m.f-1.py311.1.nbc", "m.cpython-311.pyc"):
            f = tmp_path / pkg / "__pycache__" / name
            f.write_text("")
            os.utime(f, (cache_time, cache_time))
    return tmp_path


def test_fresh_caches_stay(tmp_path):
    root = _tree(tmp_path, 200.0, 100.0, 100.0)
    assert drop_stale(root) == []
    assert len(list(root.glob("*/__pycache__/*.nb?"))) == 6


def test_cache_older_than_its_source_or_a_shared_one_goes(tmp_path):
    root = _tree(tmp_path, 200.0, 300.0, 100.0)  # integrate edited after its cache
    assert drop_stale(root) == [root / "integrate" / "__pycache__"]
    assert not list((root / "integrate" / "__pycache__").glob("*.nb?"))
    assert (root / "integrate" / "__pycache__" / "m.cpython-311.pyc").exists()  # not numba's
    root2 = _tree(tmp_path / "b", 200.0, 100.0, 300.0)  # fields (inlined by all) edited
    assert sorted(drop_stale(root2)) == sorted(root2 / p / "__pycache__"
                                               for p in ("fields", "integrate", "render"))
