"""adapt's solver: conjugate gradients preconditioned by two factorised diagonal blocks
(its solutions, its refusals, its bits), the nested-dissection order of those blocks,
and the compiled dot product and symmetric product it runs on."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import Delaunay

from deformesh_cli._ldl import dot, upper_matvec
from deformesh_cli.errors import SolverError
from deformesh_cli.ldl import LDL, dissection_order
from deformesh_cli.splitsolve import SplitSolver


def mesh(n: int, seed: int):
    """A Delaunay mesh of ``n`` random points in the unit square."""
    p = np.random.default_rng(seed).random((n, 2))
    return p, Delaunay(p).simplices


def two_unknowns(p, tri, coupling: float, seed: int):
    """An SPD system with two unknowns per node (2 j, 2 j + 1): a weighted Laplacian on
    each plus ``coupling`` times a random coupling between them (diagonally dominant),
    as its upper
    triangle by columns; the group of each unknown and where it sits."""
    n = len(p)
    rng = np.random.default_rng(seed)
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    w = rng.uniform(0.5, 2.0, size=(len(e), 2))
    L = [sp.coo_matrix((-w[:, k], (e[:, 0], e[:, 1])), shape=(n, n)) for k in range(2)]
    L = [A + A.T for A in L]
    L = [A - sp.diags(np.asarray(A.sum(axis=1)).ravel() - 0.1) for A in L]
    C = sp.coo_matrix((rng.normal(size=len(e)) * coupling, (e[:, 0], e[:, 1])), shape=(n, n))
    C = C + C.T
    grip = sp.diags(np.asarray(abs(C).sum(axis=1)).ravel())  # (diagonally dominant: SPD)
    K = sp.bmat([[L[0] + grip, C], [C.T, L[1] + grip]]).tocsr()
    order = np.arange(2 * n).reshape(2, n).T.ravel()  # node by node
    K = K[order][:, order]
    upper = sp.triu(K, format="csc")
    upper.sort_indices()
    group = np.tile([0, 1], n)
    return K.tocsc(), upper, group, np.repeat(p, 2, axis=0)


@pytest.mark.parametrize("seed, n", [(0, 40), (1, 500), (2, 3000)])
def test_the_solution_is_the_direct_ones_and_refactorising_solves_new_numbers(seed, n):
    p, tri = mesh(n, seed)
    K, upper, group, where = two_unknowns(p, tri, 0.3, seed)
    s = SplitSolver(upper.indptr, upper.indices, group, where)
    b = np.random.default_rng(seed).normal(size=K.shape[0])
    for scale in (1.0, np.linspace(1.0, 3.0, K.shape[0])):
        D = sp.diags(np.sqrt(np.broadcast_to(scale, K.shape[:1])))
        K2 = (D @ K @ D).tocsc()  # the same pattern, other numbers
        u2 = sp.triu(K2, format="csc")
        u2.sort_indices()
        assert np.array_equal(u2.indices, upper.indices)
        s.factorise(u2.data)
        x = s.solve(b)
        want = spla.spsolve(K2, b)
        assert np.abs(x - want).max() <= 1e-8 * np.abs(want).max()
        assert np.array_equal(s.solve(b), x)  # (the same bits again)


def test_uncoupled_groups_take_one_iteration():
    p, tri = mesh(400, 3)
    K, upper, group, where = two_unknowns(p, tri, 0.0, 3)
    upper = sp.csc_matrix((upper.data + 0.0, upper.indices, upper.indptr), shape=upper.shape)
    s = SplitSolver(upper.indptr, upper.indices, group, where)
    s.factorise(upper.data)
    b = np.random.default_rng(0).normal(size=K.shape[0])
    x = s.solve(b)
    assert s.iterations == 1
    assert np.abs(K @ x - b).max() <= 1e-10 * np.abs(b).max()
    assert not s.solve(np.zeros(K.shape[0])).any()


def test_an_indefinite_system_with_definite_blocks_is_refused():
    """Blocks [2] and [2], coupled by 3: the blocks factorise, the system is
    indefinite: a SolverError, not a wrong answer."""
    upper = sp.csc_matrix(np.array([[2.0, 3.0], [0.0, 2.0]]))
    s = SplitSolver(upper.indptr, upper.indices, np.array([0, 1]), np.zeros((2, 2)))
    s.factorise(upper.data)
    with pytest.raises(SolverError, match="not positive definite"):
        s.solve(np.array([1.0, 0.0]))


def test_a_block_that_is_not_positive_definite_is_refused():
    upper = sp.csc_matrix(np.array([[-2.0, 1.0], [0.0, 2.0]]))
    s = SplitSolver(upper.indptr, upper.indices, np.array([0, 1]), np.zeros((2, 2)))
    with pytest.raises(SolverError, match="not positive definite"):
        s.factorise(upper.data)


def test_the_bits_do_not_depend_on_the_blas_or_its_threads():
    """No BLAS in the solve: a fresh process with other BLAS settings gives the same bits."""
    import os
    import subprocess
    import sys

    code = (
        "import numpy as np, hashlib; from deformesh_cli.splitsolve import SplitSolver; "
        "from tests.test_splitsolve import mesh, two_unknowns; "
        "K, u, g, w = two_unknowns(*mesh(800, 5), 0.3, 5); "
        "s = SplitSolver(u.indptr, u.indices, g, w); s.factorise(u.data); "
        "print(hashlib.sha256(s.solve(np.arange(K.shape[0]) % 7.0).tobytes()).hexdigest())"
    )
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    outs = set()
    for extra in ({}, {"OPENBLAS_CORETYPE": "Prescott", "OMP_NUM_THREADS": "2",
                        "OPENBLAS_NUM_THREADS": "2"}):  # fmt: skip
        env = {**os.environ, **extra}
        r = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True,
                           text=True, check=True)  # fmt: skip
        outs.add(r.stdout.strip())
    assert len(outs) == 1, outs


def laplacian_csr(p, tri):
    n = len(p)
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    A = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    A = (A + A.T).tocsr()
    A.data[:] = -1.0
    A = (A + sp.diags(1.0 - np.asarray(A.sum(axis=1)).ravel())).tocsr()
    A.sort_indices()
    return A


def grid(a: int, b: int):
    """a x b nodes at the integers, each square split by a diagonal."""
    x, y = np.meshgrid(np.arange(a + 0.0), np.arange(b + 0.0), indexing="ij")
    q = np.arange(a * b).reshape(a, b)[:-1, :-1].ravel()
    tri = np.concatenate([np.c_[q, q + b, q + b + 1], np.c_[q, q + b + 1, q + 1]])
    return np.c_[x.ravel(), y.ravel()], tri


@pytest.mark.parametrize("seed, n", [(0, 1), (1, 17), (2, 2000)])
def test_the_dissection_order_is_a_permutation_and_solves(seed, n):
    p = np.random.default_rng(seed).random((n, 2))
    if n < 3:
        A = sp.csr_matrix(np.eye(n))
    else:
        A = laplacian_csr(p, Delaunay(p).simplices)
    order = dissection_order(p, A.indptr, A.indices)
    assert np.array_equal(np.sort(order), np.arange(n))
    b = np.arange(n, dtype=float)
    x = LDL(A, order=order).solve(b)
    assert np.abs(A @ x - b).max() <= 1e-10 * max(1.0, np.abs(b).max())


def test_the_dissection_order_orders_each_separator_after_both_halves():
    """On a grid of 40 columns the first split is between columns 19 and 20, and the
    separator column 19 (the first half's, as long as the other's): its nodes come
    last, and every node left of it before every node right of it."""
    p, tri = grid(40, 21)
    A = laplacian_csr(p, tri)
    order = dissection_order(p, A.indptr, A.indices)
    place = np.empty(len(p), dtype=int)
    place[order] = np.arange(len(p))
    col = p[:, 0]
    last = np.sort(place[col == 19])
    assert np.array_equal(last, np.arange(len(p) - 21, len(p)))
    assert place[col < 19].max() < place[col > 19].min()


def test_the_dissection_order_keeps_a_grids_factor_sparser_than_minimum_degree():
    p, tri = grid(200, 200)
    A = laplacian_csr(p, tri)
    nd = LDL(A, order=dissection_order(p, A.indptr, A.indices))
    md = LDL(A)
    flops = [float((np.diff(f._Lp).astype(float) ** 2).sum()) for f in (nd, md)]
    assert flops[0] < 0.9 * flops[1]


@pytest.mark.parametrize("seed", range(3))
def test_dot_and_the_symmetric_product_are_numpys(seed):
    rng = np.random.default_rng(seed)
    n = 300
    A = sp.random(n, n, density=0.05, random_state=rng)
    A = (A + A.T + sp.eye(n)).tocsc()
    U = sp.triu(A, format="csc")
    U.sort_indices()
    x, y = rng.normal(size=n), rng.normal(size=n)
    out = np.empty(n)
    upper_matvec(U.indptr.astype(np.int64), U.indices.astype(np.int64), U.data, x, out)
    assert np.allclose(out, A @ x, rtol=1e-13, atol=1e-13)
    assert dot(x, y) == pytest.approx(float(x @ y), rel=1e-13)
    s = 0.0
    for a, b in zip(x, y):  # (index order)
        s += a * b
    assert dot(x, y) == s


def test_two_threads_give_the_bits_of_one(monkeypatch):
    import deformesh_cli.splitsolve as split

    p, tri = mesh(2000, 6)
    K, upper, group, where = two_unknowns(p, tri, 0.3, 6)
    b = np.random.default_rng(6).normal(size=K.shape[0])
    got = []
    for parallel in (10**9, 0):
        monkeypatch.setattr(split, "PARALLEL_UNKNOWNS", parallel)
        s = SplitSolver(upper.indptr, upper.indices, group, where)
        s.factorise(upper.data)
        s.factorise(upper.data * 2.0)  # (a refactorisation in threads too)
        got.append(s.solve(b))
    assert s._pool is not None
    assert np.array_equal(got[0], got[1])


@pytest.mark.parametrize("seed, n", [(0, 3), (1, 40), (2, 700), (3, 4000)])
def test_the_supernodal_factor_solves_as_the_column_one_does(seed, n):
    """In minimum-degree and nested-dissection order: the supernodal L D L^T's
    solution is the column-by-column one's to round-off, the residual is round-off,
    a refactorisation with new numbers solves the new system, and the same numbers
    give the same bits."""
    from deformesh_cli.ldl import SupernodalLDL

    p, tri = mesh(n, seed)
    A = laplacian_csr(p, tri)
    b = np.random.default_rng(seed).normal(size=n)
    for order in (None, dissection_order(p, A.indptr, A.indices)):
        s = SupernodalLDL(A, order=order)
        x = s.solve(b)
        assert np.abs(x - LDL(A, order=order).solve(b)).max() <= 1e-12 * np.abs(x).max()
        assert np.abs(A @ x - b).max() <= 1e-12 * np.abs(b).max() * n
        A2 = sp.csr_matrix((A.data * np.linspace(1, 2, len(A.data)), A.indices, A.indptr))
        A2 = (A2 + A2.T) * 0.5 + sp.eye(n)
        A2 = sp.csr_matrix((np.asarray(A2[A.nonzero()]).ravel(), A.nonzero()), shape=A.shape)
        A2.sort_indices()
        assert np.array_equal(A2.indices, A.indices)
        s.update(A2)
        y = s.solve(b)
        assert np.abs(A2 @ y - b).max() <= 1e-10 * np.abs(b).max()
        assert np.array_equal(SupernodalLDL(A2, order=order).solve(b), y)


def test_the_supernodal_factor_refuses_a_matrix_that_is_not_positive_definite():
    from deformesh_cli.ldl import SupernodalLDL

    p, tri = mesh(200, 4)
    A = laplacian_csr(p, tri)
    neg = sp.csr_matrix((-A.data, A.indices, A.indptr), shape=A.shape)
    with pytest.raises(SolverError, match="not positive definite"):
        SupernodalLDL(neg)


@pytest.mark.parametrize("group", [[0, 0, 0], [1, 1, 1], [0, 1, 1]])
def test_a_group_with_no_unknown_is_skipped(group):
    """All unknowns in one group (a mesh whose free nodes all slide one way): the
    other block is empty and the solve is the direct one's."""
    K = np.array([[4.0, 1.0, 0.5], [1.0, 3.0, 1.0], [0.5, 1.0, 2.0]])
    upper = sp.csc_matrix(np.triu(K))
    s = SplitSolver(upper.indptr, upper.indices, np.array(group), np.zeros((3, 2)))
    for scale in (1.0, 2.0):
        s.factorise(upper.data * scale)
        b = np.array([1.0, -2.0, 0.5])
        assert np.allclose(s.solve(b), np.linalg.solve(K * scale, b), rtol=1e-12, atol=0)


def test_both_factors_take_an_empty_system():
    """A system with no unknown (a group of the split solver left empty): factorised,
    refactorised and solved, one right-hand side or two."""
    from deformesh_cli.divcurl import SymmetricCSR
    from deformesh_cli.ldl import SupernodalLDL

    empty = SymmetricCSR(np.zeros(0), np.zeros(0, np.int64), np.zeros(1, np.int64), (0, 0))
    for cls in (LDL, SupernodalLDL):
        for order in (None, np.zeros(0, dtype=np.int64)):
            f = cls(empty, order=order)
            f.update(empty)
            assert f.solve(np.zeros(0)).shape == (0,)
            assert f.solve(np.zeros((0, 2))).shape == (0, 2)
