"""Regenerate datasets/hotroom.h5 from the OpenFOAM heated-room export in ../shared/datasets.

    .venv/bin/python datasets/make_hotroom.py [SERIES_FILE]

Reads the five foamToVTK snapshots listed in hotroom.vtu.series with flowkit's own .vtu reader
(the 41 x 21 x 41 node lattice is rebuilt exactly), keeps the node (point) data U, T and p in the
files' float32, and writes one flowkit HDF5 field file with /snapshots/0000..0004 (gzip + shuffle),
each array and coordinate with its CF ``units`` (U m/s, T K, p m2/s2 -- kinematic in this
Boussinesq solver --, x y z m).
"""

import sys
from pathlib import Path

import numpy as np

from flowkit import Field
from flowkit.fields.readers import load_field, load_series
from flowkit.fields.writers import save_series

ROOT = Path(__file__).resolve().parents[1]
SERIES = ROOT / ".." / "shared" / "datasets" / "hotroom" / "hotroom.vtu.series"
OUT = ROOT / "datasets" / "hotroom.h5"
KEEP = ("T", "p")


def main(series=SERIES, out=OUT):
    fields = []
    for t, path in load_series(series):
        f = load_field(path)
        for n in KEEP:
            # the files store float32: converting back loses nothing
            assert np.array_equal(f.scalars[n].astype(np.float32), f.scalars[n]), n
        # the reader gives U and T their OpenFOAM units; this solver's p is kinematic
        units = {**{n: u for n, u in f.units.items() if n in ("U", *KEEP)}, "p": "m2/s2"}
        fields.append(Field(f.grid, f.vector, {n: f.scalars[n] for n in KEEP}, time=t,
                            units=units, length_units=f.length_units))
        print(f"t = {t:g}: {path.name}, grid {f.grid.shape}")
    attrs = {
        "title": "OpenFOAM hotRoom (buoyantBoussinesqPimpleFoam), 40 x 20 x 40 cells, node data",
        "source": "foamToVTK export " + ", ".join(p.name for _, p in load_series(series)),
        "history": "datasets/make_hotroom.py: .vtu point data, lattice rebuilt exactly, float32",
        "units": "U m/s, T K, p (kinematic) m2/s2, x y z m, time s",
    }
    save_series(fields, out, dtype=np.float32, compression="gzip", attrs=attrs)
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else SERIES)
