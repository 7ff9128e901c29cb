import numpy as np
import pytest

from deformesh_cli.deform import deform
from deformesh_cli.errors import FoldError
from deformesh_cli.geometry import signed_areas
from deformesh_cli.select import Grid, grid_triangles


def _grid(n=10):
    g = Grid(0, 0, 1, 1, n, n)
    return g, g.coords(), grid_triangles(g, np.zeros(n * n, np.uint8))


def test_nodes_land_exactly_and_nothing_folds():
    g, pts, tri = _grid()
    path = g.node_id([4, 5, 5, 4], [4, 4, 5, 5])
    targets = np.array([(3.7, 3.9), (5.2, 3.6), (5.5, 5.1), (3.9, 5.3)]) + 1e-3 / 3
    out, st = deform(pts, tri, path, targets, g.boundary_nodes(), steps=10)
    assert np.array_equal(out[path], targets)  # bit-exact arrival
    assert (signed_areas(out, tri) > 0).all()
    assert np.array_equal(out[g.boundary_nodes()], pts[g.boundary_nodes()])
    assert st.solves == 10 and st.halvings == 0


def _rotated_ring(angle_deg, n=16):
    g = Grid(0, 0, 1, 1, n, n)
    pts, tri = g.coords(), grid_triangles(g, np.zeros(n * n, np.uint8))
    c = np.array([8.0, 8.0])
    ring = [(i, j) for i in range(5, 12) for j in range(5, 12) if max(abs(i - 8), abs(j - 8)) == 3]
    path = g.node_id(*np.array(ring).T)
    a = np.radians(angle_deg)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return g, pts, tri, path, (pts[path] - c) @ rot.T + c


def test_a_step_that_would_fold_is_refined():
    # a ring of nodes turned 45 degrees in one step folds the cells around it;
    # refined steps, each solved on the moved mesh, get there without folding
    g, pts, tri, path, targets = _rotated_ring(45)
    out, st = deform(pts, tri, path, targets, g.boundary_nodes(), steps=1)
    assert st.halvings > 0 and st.solves > 1
    assert np.array_equal(out[path], targets)
    assert (signed_areas(out, tri) > 0).all()


def test_unreachable_rotation_is_a_fold_error():
    g, pts, tri, path, targets = _rotated_ring(90)
    with pytest.raises(FoldError, match="fold"):
        deform(pts, tri, path, targets, g.boundary_nodes(), steps=2)


def test_unreachable_target_is_a_fold_error_not_a_folded_mesh():
    # two neighbouring nodes asked to swap places cannot avoid folding
    g, pts, tri = _grid()
    path = g.node_id([4, 5], [5, 5])
    targets = pts[path][::-1].copy()
    with pytest.raises(FoldError, match="fold"):
        deform(pts, tri, path, targets, g.boundary_nodes(), steps=4)
