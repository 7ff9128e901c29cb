"""On Appendix A's uniform grid, whose path is searched for, every contour gets an
answer within a time bound that grows with its size: a mesh that passes an
independent contract check, or a one-line refusal.  The bound is lowered here so the
test runs in seconds; what is tested is that the search stops at the bound,
whatever it is.  (The graded grid is constructed: it reads no clock.)"""

import time

import meshio
import numpy as np
import pytest

from deformesh_cli import deadline

from .independent import contract_problems
from .random_polygons import KINDS, write_csv

#: What finishing a selection found (deforming, triangulating, writing) and the last
#: piece of search before the next check may add to the bound, in seconds.
FINISH = 10.0


def _jagged(seed: int, kind: str, n: int):
    return KINDS[kind](np.random.default_rng(seed), n)


#: (no comb: the uniform grid finds its path in time, and its mesh of millions of
#: triangles then takes a minute and more, which the bound does not cover)
CASES = [(0, "angle-sorted", 500), (1, "uneven-star", 460),
         (3, "angle-sorted", 300), (4, "spikes", 120), (5, "uneven-star", 250)]  # fmt: skip


@pytest.mark.parametrize("seed,kind,n", CASES, ids=[f"{k}-{n}" for _, k, n in CASES])
def test_a_jagged_polygon_is_answered_within_its_bound(run, tmp_path, monkeypatch, seed, kind, n):
    monkeypatch.setattr(deadline, "SEARCH_BASE", 2.0)
    monkeypatch.setattr(deadline, "SEARCH_PER_POINT", 0.004)
    points, ring = _jagged(seed, kind, n)
    f = tmp_path / "c.csv"
    write_csv(f, points, ring)
    t = time.perf_counter()
    r = run("all", f, "-o", tmp_path / "m.msh", "-q", "--grid", "uniform")
    took = time.perf_counter() - t
    assert took <= deadline.search_bound(len(points)) + FINISH, took
    if r.exit_code == 0:
        m = meshio.read(tmp_path / "m.msh")
        assert contract_problems(m.points, m.cells_dict["triangle"], points, ring) == []
    else:
        assert r.exit_code == 1 and r.stderr.count("\n") == 1, r.stderr
        assert r.stderr.startswith(f"deformesh: error: {f}: ")
        assert not (tmp_path / "m.msh").exists()


def test_the_search_stops_at_the_bound(monkeypatch):
    """The bound itself: a search loop that checks it stops once it has passed."""
    with deadline.limit(0.2):
        t = time.perf_counter()
        with pytest.raises(deadline.TimeUp, match="time bound of 0 s"):
            while True:
                deadline.check()
        assert 0.2 <= time.perf_counter() - t < 1.0
    deadline.check()  # (outside a bound nothing stops)
    with deadline.limit(0.1), deadline.limit(100):  # an enclosing bound that ends sooner stays
        time.sleep(0.15)
        with pytest.raises(deadline.TimeUp):
            deadline.check()
