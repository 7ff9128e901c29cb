import numpy as np
import scipy.sparse.linalg as spla

from deformesh_cli.deform import LinearSolver
from deformesh_cli.divcurl import Assembler, assemble_coupled
from deformesh_cli.select import Grid, grid_triangles


def _mesh(n=12, seed=0):
    g = Grid(0, 0, 1 / n, 1 / n, n, n)
    rng = np.random.default_rng(seed)
    tri = grid_triangles(g, rng.integers(0, 2, n * n).astype(np.uint8))
    pts = g.coords()
    inner = np.setdiff1d(np.arange(g.n_nodes), g.boundary_nodes())
    pts[inner] += rng.uniform(-0.2, 0.2, (len(inner), 2)) / n  # a non-uniform mesh
    return g, pts, tri


def _split_solve(pts, tri, dirichlet, ud, method="direct"):
    asm = Assembler(tri, len(pts), dirichlet)
    K, rhs = asm.system(pts, ud)
    u = ud.copy()
    u[asm.free] = LinearSolver(method).solve(K, rhs)
    return u


def test_linear_fields_are_reproduced_exactly():
    # div and curl of a linear field are constants; with curl-free, div-free data
    # (a harmonic linear field) P1 LSFEM must reproduce it at every node
    g, pts, tri = _mesh()
    dirichlet = np.zeros(len(pts), bool)
    dirichlet[g.boundary_nodes()] = True
    field = np.column_stack([0.3 * pts[:, 0] + 0.7 * pts[:, 1], 0.7 * pts[:, 0] - 0.3 * pts[:, 1]])
    for method in ("direct", "amg"):
        u = _split_solve(pts, tri, dirichlet, np.where(dirichlet[:, None], field, 0.0), method)
        assert np.abs(u - field).max() < 1e-7


def test_split_equals_coupled_lsfem_with_interior_dirichlet_nodes():
    g, pts, tri = _mesh(10, seed=3)
    n = len(pts)
    rng = np.random.default_rng(1)
    dirichlet = np.zeros(n, bool)
    dirichlet[g.boundary_nodes()] = True
    inner_fixed = rng.choice(np.flatnonzero(~dirichlet), 12, replace=False)
    dirichlet[inner_fixed] = True
    ud = np.zeros((n, 2))
    ud[inner_fixed] = rng.normal(size=(12, 2)) * 0.01
    u_split = _split_solve(pts, tri, dirichlet, ud)
    A, b = assemble_coupled(pts, tri)
    dof_fixed = np.concatenate([dirichlet, dirichlet])
    x = np.concatenate([ud[:, 0], ud[:, 1]])
    free = ~dof_fixed
    rhs = b[free] - A[free][:, dof_fixed] @ x[dof_fixed]
    x[free] = spla.spsolve(A[free][:, free].tocsc(), rhs)
    u_coupled = np.column_stack([x[:n], x[n:]])
    assert np.abs(u_split - u_coupled).max() < 1e-12


def test_coupling_block_vanishes_off_the_outer_boundary():
    g, pts, tri = _mesh(8, seed=5)
    n = len(pts)
    A, _ = assemble_coupled(pts, tri)
    inner = np.setdiff1d(np.arange(n), g.boundary_nodes())
    C = A[:n, n:].toarray()
    assert np.abs(C[np.ix_(inner, np.arange(n))]).max() < 1e-12
    # but not on it (the split is a property of U = 0 on the box, not of the element)
    assert np.abs(C).max() > 1e-3
