"""The sparse factorisation of adapt's systems (QDLDL): solutions, refactorisation on
the same pattern, a singular matrix refused, and the same bits whatever the BLAS."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from deformesh_cli.cholesky import Cholesky
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


def test_a_singular_matrix_is_refused():
    K = spd(50, 3).tolil()
    K[7, :] = 0.0
    K[:, 7] = 0.0
    with pytest.raises(SolverError, match="singular"):
        Cholesky().factorise(upper(K.tocsc()))


def test_the_bits_do_not_depend_on_the_blas_or_its_threads():
    """QDLDL uses no BLAS: a fresh process with other BLAS settings gives the same bits."""
    import hashlib
    import os
    import subprocess
    import sys

    code = (
        "import numpy as np, scipy.sparse as sp, hashlib; "
        "from deformesh_cli.cholesky import Cholesky; "
        "from tests.test_cholesky import spd, upper; "
        "c = Cholesky(); c.factorise(upper(spd(400, 5))); "
        "print(hashlib.sha256(c.solve(np.arange(400.0)).tobytes()).hexdigest())"
    )
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    outs = set()
    for extra in ({}, {"OPENBLAS_CORETYPE": "Prescott", "OMP_NUM_THREADS": "2",
                        "OPENBLAS_NUM_THREADS": "2"}):  # fmt: skip
        env = {**os.environ, **extra}
        r = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True,
                           text=True, check=True)  # fmt: skip
        outs.add(r.stdout.strip())
    c = Cholesky()
    c.factorise(upper(spd(400, 5)))
    outs.add(hashlib.sha256(c.solve(np.arange(400.0)).tobytes()).hexdigest())
    assert len(outs) == 1, outs
