"""The numba cache: drop_stale removes caches that a newer source (own package or a shared one)
outdates; a read-only install still gets a cache; Dask workers share one."""

import os

import pytest

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


# -- where the cache lives -------------------------------------------------------------------
READ_ONLY_RUN = """
import sys
from pathlib import Path
import numpy as np
import flowkit
from flowkit import warmup
f = warmup.stand_in()
v, status = f.sample_scalar("T", np.array([[1.5, 2.0, 3.0]]))  # compiles, and stores the code
assert abs(v[0] - 1.5) < 1e-12, v
print(warmup.cache_location())
"""


def test_read_only_install_without_a_home_caches_in_the_temp_dir(tmp_path):
    """A wheel in a read-only site-packages, run by a user whose home is not writable either:
    numba would refuse to define the kernels; flowkit points it at the temporary directory."""
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    site = tmp_path / "site"
    src = Path(__file__).resolve().parent.parent / "flowkit"
    shutil.copytree(src, site / "flowkit", ignore=shutil.ignore_patterns("__pycache__"))
    (site / "home").mkdir()
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "XDG_"))}
    env.update(PYTHONPATH=str(site), HOME=str(site / "home"), TMPDIR=str(tmp))
    cmd = [sys.executable, "-c", READ_ONLY_RUN]
    if os.geteuid() == 0:  # root writes anywhere: mount the install read-only in a namespace
        if shutil.which("unshare") is None:
            pytest.skip("no unshare to mount the install read-only")
        ro = 'mount --bind "$0" "$0" && mount -o remount,ro,bind "$0" "$0" && exec "$@"'
        cmd = ["unshare", "--mount", "sh", "-c", ro, str(site), *cmd]
    else:
        for p in [site, *site.rglob("*")]:
            p.chmod(p.stat().st_mode & ~0o222)
    p = subprocess.run(cmd, check=False, env=env, cwd=tmp, capture_output=True, text=True, timeout=600)
    if os.geteuid() == 0 and "mount" in p.stderr and p.returncode != 0:
        pytest.skip(f"cannot mount read-only here: {p.stderr.strip()[-200:]}")
    assert p.returncode == 0, p.stderr[-3000:]
    where = Path(p.stdout.strip().splitlines()[-1])
    assert where.is_relative_to(tmp / f"flowkit-numba-{os.getuid()}"), where
    assert list(tmp.rglob("interp.*_sample_range*.nbi"))  # the code was stored there
    assert not list(site.rglob("*.nb?"))


def test_a_second_jobs_fresh_workers_load_the_shared_cache(tmp_path):
    """Every worker pointed at one NUMBA_CACHE_DIR: the first job compiles the kernels once,
    the workers of a later job (fresh processes) load them and compile under a second each."""
    distributed = pytest.importorskip("distributed")
    import logging

    import numpy as np

    from flowkit import warmup
    from flowkit.datasets import hotroom_path
    from flowkit.distributed import trace_distributed
    from flowkit.integrate.options import TraceOptions

    shared = tmp_path / "numba"
    seeds = np.random.default_rng(0).uniform([0.5, 0.5, 0.5], [9.5, 4.5, 9.5], (40, 3))

    def job(n_workers, name):
        with distributed.LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                      dashboard_address=":0", silence_logs=logging.CRITICAL,
                                      env={"NUMBA_CACHE_DIR": str(shared)}) as cluster, \
                distributed.Client(cluster) as c:
            c.run(warmup.record)
            trace_distributed(hotroom_path(), seeds, tmp_path / name, TraceOptions(max_length=5),
                              client=c, snapshots=[4], chunk_seeds=10, progress=False)
            return c.run(warmup.recorded)

    first = job(1, "a.h5")
    assert sum(n for n, _ in first.values()) >= 5 and sum(s for _, s in first.values()) > 1.0
    assert list(shared.rglob("kernel._advance_lines-*.nbi"))
    second = job(2, "b.h5")
    assert len(second) == 2
    for worker, (n, secs) in second.items():
        assert secs < 1.0, (worker, n, secs)
