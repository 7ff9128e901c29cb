"""The coarsening of stage 3: what it removes, and what it may never change."""

from pathlib import Path

import numpy as np
import pytest

from deformesh_cli import coarsen, pipeline
from deformesh_cli.geometry import signed_areas
from deformesh_cli.quality import measures
from deformesh_cli.readers import load_contour

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
CASES = ["circle.csv", "peanut.csv", "bracket.svg", "naca0012.csv"]


def _captured(monkeypatch, path, **options):
    """The mesh handed to the coarsening, its size field, and what came back."""
    seen = {}
    real = coarsen.coarsen

    def spy(mesh, size):
        out, removed = real(mesh, size)
        seen.update(before=mesh, size=size, after=out, removed=removed)
        return out, removed

    monkeypatch.setattr(pipeline._coarsen, "coarsen", spy)
    res = pipeline.mesh_contour(load_contour(SAMPLES / path), **options)
    return seen, res


def _edges(tri):
    e = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0, return_counts=True)


@pytest.mark.parametrize("path", CASES)
def test_coarsening_keeps_the_boundary_and_makes_only_allowed_triangles(monkeypatch, path):
    seen, res = _captured(monkeypatch, path, exterior=path.startswith("naca"))
    before, after, size = seen["before"], seen["after"], seen["size"]
    assert seen["removed"] > 0 and res.report["coarsened_nodes"] == seen["removed"]
    assert len(after.points) == len(before.points) - seen["removed"]
    # boundary nodes, their numbers and the boundary edges: the same
    nb = before.n_contour + before.n_extra + before.n_box
    assert np.array_equal(after.points[:nb], before.points[:nb])
    assert np.array_equal(after.lines, before.lines)
    # a triangulation of the same domain: counter-clockwise, same area, every inner
    # edge in two triangles and every boundary edge in one
    area = signed_areas(after.points, after.triangles)
    assert (area > 0).all()
    assert np.isclose(area.sum(), signed_areas(before.points, before.triangles).sum(), rtol=1e-12)
    edges, uses = _edges(after.triangles)
    boundary = {tuple(sorted(e)) for e in after.lines.tolist()}
    on_boundary = np.array([tuple(e) in boundary for e in edges.tolist()])
    assert (uses[on_boundary] == 1).all() and (uses[~on_boundary] == 2).all()
    assert on_boundary.sum() == len(after.lines)
    # (node k of the result is node old[k] before: nodes only go, in order)
    lookup = {p: k for k, p in enumerate(map(tuple, before.points.tolist()))}
    old = np.array([lookup[p] for p in map(tuple, after.points.tolist())])
    assert (np.diff(old) > 0).all()
    # the triangles it made: smallest angle at least ANGLE, and their new edges at
    # most LONGEST times the size field (the mean of their ends')
    kept = {tuple(t) for t in np.sort(before.triangles, axis=1).tolist()}
    made = np.array([tuple(t) not in kept for t in np.sort(old[after.triangles], axis=1).tolist()])
    assert made.any()
    angle = measures(after.points, after.triangles[made])[0]
    at_boundary = (after.triangles[made] < nb).any(axis=1)
    assert angle.min() >= coarsen.ANGLE - 1e-9
    assert angle[at_boundary].min(initial=90) >= coarsen.EDGE_ANGLE - 1e-9
    had = {tuple(e) for e in _edges(before.triangles)[0].tolist()}
    e = _edges(after.triangles[made])[0]
    new = np.array([tuple(sorted(x)) not in had for x in old[e].tolist()])
    assert new.any()
    e = e[new]
    need = size(after.points)
    length = np.hypot(*(after.points[e[:, 0]] - after.points[e[:, 1]]).T)
    bound = coarsen.LONGEST * 0.5 * (need[e[:, 0]] + need[e[:, 1]])
    assert (length <= bound * (1 + 1e-12)).all()


def test_coarsening_ends_with_no_collapse_left_and_is_repeatable(monkeypatch):
    seen, _ = _captured(monkeypatch, "peanut.csv")
    again, _ = coarsen.coarsen(seen["before"], seen["size"])
    assert np.array_equal(again.points, seen["after"].points)
    assert np.array_equal(again.triangles, seen["after"].triangles)
    # run on its own result, it finds nothing more to take
    twice, more = coarsen.coarsen(seen["after"], seen["size"])
    assert more == 0 and twice is seen["after"]


def test_the_paper_grid_and_size_functions_are_not_coarsened():
    c = load_contour(SAMPLES / "peanut.csv")
    assert pipeline.mesh_contour(c, grid="uniform").report["coarsened_nodes"] == 0
    assert pipeline.mesh_contour(c, size="0.05 + d").report["coarsened_nodes"] == 0
    assert pipeline.mesh_contour(c).report["coarsened_nodes"] > 0


def _collapse_reference(tri, stars, deg, alive, wa, wb):
    """The collapses of one round all at once, in numpy (what the compiled loop must
    give: the same triangles and the same stars, in order)."""
    w = stars.shape[1]
    sa = stars[wa]
    va = np.arange(w) < deg[wa, None]
    ids = sa[va]
    t = tri[ids]
    owner = np.repeat(wa, va.sum(axis=1))
    into = np.repeat(wb, va.sum(axis=1))
    holds_b = (t == into[:, None]).any(axis=1)
    t = np.where(t == owner[:, None], into[:, None], t)
    tri[ids] = t
    dead = ids[holds_b]
    alive[dead] = False
    # b's star: its own and a's, without the dead; the two across lose theirs
    sb = stars[wb]
    vb = np.arange(w) < deg[wb, None]
    merged = np.concatenate([np.where(vb, sb, -1), np.where(va, sa, -1)], axis=1)
    across = np.unique(tri[dead].ravel())
    across = across[~np.isin(across, wb)]
    rows_nodes = np.concatenate([wb, across])
    blocks = [merged]
    sx = stars[across]
    vx = np.arange(w) < deg[across, None]
    blocks.append(np.concatenate([np.where(vx, sx, -1), np.full((len(across), w), -1)], axis=1))
    block = np.concatenate(blocks)
    keep = block >= 0
    keep[keep] = ~np.isin(block[keep], dead)
    count = keep.sum(axis=1)
    order = np.argsort(~keep, axis=1, kind="stable")
    packed = np.take_along_axis(block, order, axis=1)
    width = max(w, int(count.max()) if len(count) else w)
    if width > w:
        stars = np.concatenate([stars, np.full((len(stars), width - w), -1)], axis=1)
    packed = np.where(np.arange(packed.shape[1]) < count[:, None], packed, -1)[:, :width]
    stars[rows_nodes] = np.pad(
        packed, ((0, 0), (0, max(0, width - packed.shape[1]))), constant_values=-1
    )
    deg[rows_nodes] = count
    deg[wa] = 0
    return stars


@pytest.mark.parametrize("path", ["peanut.csv", "naca0012.csv"])
def test_the_compiled_collapses_are_the_numpy_ones(monkeypatch, path):
    """Coarsening with the compiled collapse loop and with the numpy reference makes the
    same mesh, node for node and triangle for triangle."""
    seen, _ = _captured(monkeypatch, path)
    got, removed = coarsen.coarsen(seen["before"], seen["size"])
    monkeypatch.setattr(coarsen, "_collapse", _collapse_reference)
    want, removed_ref = coarsen.coarsen(seen["before"], seen["size"])
    assert removed == removed_ref > 0
    assert np.array_equal(got.points, want.points)
    assert np.array_equal(got.triangles, want.triangles)
