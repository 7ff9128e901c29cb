"""The sparse Cholesky solver of adapt's systems: solutions, refactorisation on the
same pattern, and a matrix that is not positive definite refused."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from deformesh_cli.cholesky import Cholesky, _runs_haswell_kernels, cvxopt_module
from deformesh_cli.errors import SolverError


def spd(n: int, seed: int) -> sp.csc_matrix:
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=0.02, random_state=rng, format="csc")
    return (A @ A.T + sp.eye(n) * n * 0.01).tocsc()


def upper(K: sp.csc_matrix) -> sp.csc_matrix:
    u = sp.triu(K, format="csc")
    u.sort_indices()
    return u


def test_solves_and_refactorises_on_the_same_pattern():
    K1 = spd(300, 1)
    D = sp.diags(np.linspace(1.0, 2.0, 300))
    K2 = (D @ K1 @ D).tocsc()  # same pattern, other numbers
    K3 = spd(300, 4)  # another pattern
    b = np.random.default_rng(2).random((300, 2))
    chol = Cholesky()
    for K in (K1, K2, K3):
        chol.factorise(upper(K))
        x = chol.solve(b)
        assert x.shape == b.shape
        assert np.allclose(x, spla.spsolve(K, b), rtol=1e-9, atol=1e-12)
        assert np.allclose(chol.solve(b[:, 0]), x[:, 0], rtol=0, atol=0)
    assert chol.symbolic == 2  # K2 reused K1's ordering


def test_a_matrix_that_is_not_positive_definite_is_refused():
    K = spd(50, 3)
    K = (K - sp.eye(50) * 1e3).tocsc()
    with pytest.raises(SolverError, match="not positive definite"):
        Cholesky().factorise(upper(K))


def test_cvxopts_module_wide_options_are_left_as_they_were():
    """Another cvxopt user's CHOLMOD options survive a factorisation and a solve."""
    cholmod = cvxopt_module().cholmod

    before = dict(cholmod.options)
    cholmod.options["supernodal"] = 0  # simplicial, as another user might ask
    try:
        K = spd(200, 5)
        chol = Cholesky()
        chol.factorise(upper(K))
        x = chol.solve(np.ones(200))
        assert cholmod.options == {**before, "supernodal": 0}
        assert np.allclose(x, spla.spsolve(K, np.ones(200)), rtol=1e-9)
    finally:
        cholmod.options.clear()
        cholmod.options.update(before)


def test_a_given_order_solves_the_same_system():
    """A fill-reducing order given by the caller (here a random one) is the one CHOLMOD
    uses, and the solution is the same to round-off."""
    K = spd(300, 6)
    b = np.random.default_rng(7).random(300)
    order = np.random.default_rng(8).permutation(300)
    chol = Cholesky(order=order)
    chol.factorise(upper(K))
    assert np.allclose(chol.solve(b), spla.spsolve(K, b), rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError):
        Cholesky(order=np.zeros(300, dtype=np.int64)).factorise(upper(K))  # (not a permutation)


def test_cvxopts_blas_is_held_to_the_same_kernels_on_every_avx2_processor():
    """In a fresh process (no OPENBLAS_CORETYPE of the user's), cvxopt's OpenBLAS runs
    its Haswell kernels wherever the processor has AVX2 and FMA, and the environment is
    left as it was."""
    import os
    import subprocess
    import sys

    if not _runs_haswell_kernels():
        pytest.skip("this processor has no AVX2 and FMA: OpenBLAS keeps its own kernels")
    code = (
        "import os; from deformesh_cli.cholesky import cvxopt_module; cvxopt_module(); "
        "from threadpoolctl import threadpool_info; "
        "print([d['architecture'] for d in threadpool_info() if 'cvxopt' in d['filepath']], "
        "'OPENBLAS_CORETYPE' in os.environ)"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.stdout.strip() == "['Haswell'] False", out.stderr
