"""The boundary groups' names reach a solver built on meshio: scikit-fem's ``Mesh.load``
finds ``contour``, ``hole_1`` and the box sides in every format that can hold names, in
what ``all`` and ``adapt`` write, and a Dirichlet problem set on them by name solves."""

import numpy as np
import pytest

from .conftest import SAMPLES

skfem = pytest.importorskip("skfem")

FAR_FIELD = ["contour", "bottom", "right", "top", "left"]

#: (output name, extra options of ``all``): the formats whose names a meshio reader sees
OUTPUTS = [
    ("m.msh", ["--msh-version", "2.2"]),
    ("m.msh", ["--msh-version", "4.1"]),
    ("m.vtu", []),
    ("m.xdmf", []),
]


def _solves_by_name(path, hot: str, cold: list[str]):
    """Load ``path`` in scikit-fem, take u = 1 on the boundary named ``hot`` and 0 on
    those named ``cold``, solve Laplace's equation: the names must be there, and the
    solution lies between 0 and 1 (the maximum principle) with the given values on them."""
    from skfem import Basis, ElementTriP1, asm, condense, solve
    from skfem.models.poisson import laplace

    m = skfem.MeshTri.load(str(path))
    assert m.boundaries is not None, path
    assert {hot, *cold} <= set(m.boundaries), (path, sorted(m.boundaries))
    basis = Basis(m, ElementTriP1())
    one = basis.get_dofs(m.boundaries[hot]).all()
    zero = np.concatenate([basis.get_dofs(m.boundaries[name]).all() for name in cold])
    u = np.zeros(basis.N)
    u[one] = 1.0
    fixed = np.concatenate([one, zero])
    u = solve(*condense(asm(laplace, basis), np.zeros(basis.N), x=u, D=fixed))
    assert u.min() >= -1e-9 and u.max() <= 1 + 1e-9
    assert np.all(u[one] == 1.0) and np.all(u[zero] == 0.0)
    free = np.setdiff1d(np.arange(basis.N), fixed)
    assert 0.0 < u[free].mean() < 1.0


@pytest.mark.parametrize("name, extra", OUTPUTS, ids=["msh22", "msh41", "vtu", "xdmf"])
def test_all_writes_names_a_meshio_solver_finds(run, tmp_path, name, extra):
    out = tmp_path / name
    r = run(
        "all", SAMPLES / "naca0012.csv", "--exterior", "--box=-2,-2,3,2", "-o", out, "-q", *extra
    )
    assert r.exit_code == 0, r.stderr
    _solves_by_name(out, "contour", FAR_FIELD[1:])
    hole = tmp_path / ("hole_" + name)
    assert run("all", SAMPLES / "bracket.svg", "-o", hole, "-q", *extra).exit_code == 0
    _solves_by_name(hole, "hole_1", ["contour"])


@pytest.mark.parametrize("source", ["f.vtu", "f.msh", "f.su2", "f.xdmf"])
@pytest.mark.parametrize("target", ["a.msh", "a.vtu", "a.xdmf"])
def test_adapt_carries_the_names_from_every_input_to_every_output(run, tmp_path, source, target):
    src = tmp_path / source
    r = run("all", SAMPLES / "naca0012.csv", "--exterior", "--box=-2,-2,3,2", "-o", src, "-q")
    assert r.exit_code == 0, r.stderr
    out = tmp_path / target
    monitor = "1 + 2 * exp(-10 * ((x + 1)**2 + (y - 1)**2))"  # (away from the body)
    r = run("adapt", src, "-o", out, "--monitor", monitor, "--steps", "2", "-q")
    assert r.exit_code == 0, r.stderr
    _solves_by_name(out, "contour", FAR_FIELD[1:])


def test_vtk_keeps_the_group_tags_for_readers_that_look_by_number(run, tmp_path):
    """Legacy VTK has no place meshio reads names from: the tags are there (``group``),
    the names in the file for VTK's own readers (docs/formats.md says which)."""
    import meshio

    out = tmp_path / "m.vtk"
    r = run("all", SAMPLES / "naca0012.csv", "--exterior", "--box=-2,-2,3,2", "-o", out, "-q")
    assert r.exit_code == 0
    m = meshio.read(out)
    assert sorted(np.unique(np.concatenate(m.cell_data["group"]))) == [1, 2, 3, 4, 5, 6]
