"""`flowkit bench precision --quick` runs end to end and its table says true things."""

import csv

import numpy as np
from PIL import Image

from flowkit.cli import main


def test_bench_precision_quick(tmp_path):
    png = tmp_path / "wp.png"
    rc = main(["bench", "precision", "--quick", "--no-peers", "--seeds", "4",
               "--problems", "rotation,stiff linear", "--out", str(tmp_path), "--plot", str(png)])
    assert rc == 0
    with open(tmp_path / "precision_quick.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["problem"] for r in rows} == {"rotation", "stiff linear"}
    assert {r["method"] for r in rows} == {"dopri5", "cashkarp", "bs23", "dop853", "ros34pw2"}
    assert all(int(r["failed"]) == 0 for r in rows)

    def get(problem, method, tol, aware="True"):
        return next(r for r in rows if r["problem"] == problem and r["method"] == method
                    and float(r["tol"]) == tol and r["cell_aware"] == aware)

    # exact references: DP5's error follows the tolerance (within 10x) and shrinks with it
    for tol in (1e-3, 1e-6, 1e-9):
        assert float(get("rotation", "dopri5", tol)["median_err"]) < 10 * tol
    assert float(get("rotation", "dopri5", 1e-9)["median_err"]) < 1e-4 * float(
        get("rotation", "dopri5", 1e-3)["median_err"])
    # the stiff field: ROS34PW2 matches dopri5's accuracy with >= 10x fewer steps
    d, r = get("stiff linear", "dopri5", 1e-6), get("stiff linear", "ros34pw2", 1e-6)
    assert float(r["median_err"]) < 3 * float(d["median_err"]) + 1e-6
    assert 10 * float(r["steps"]) <= float(d["steps"])
    md = (tmp_path / "precision_quick.md").read_text()
    assert "ros34pw2 against dopri5" in md and "| rotation | flowkit | dopri5 |" in md
    im = np.asarray(Image.open(png))
    assert im.shape[0] > 200 and im.std() > 10  # a drawn figure, not a blank canvas
