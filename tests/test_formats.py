"""The format registry: every format round-trips, and carries what it says it carries."""

import contextlib
import io

import meshio
import numpy as np
import pytest

from deformesh_cli import formats, mesh_contour
from deformesh_cli.errors import OptionError
from deformesh_cli.formats import FORMATS
from deformesh_cli.readers import load_contour

from .conftest import SAMPLES


@pytest.fixture(scope="module")
def mesh():
    """An exterior mesh of an SVG with a hole: several boundary groups, extra nodes."""
    m = mesh_contour(load_contour(SAMPLES / "bracket.svg"), exterior=True).mesh
    assert len(m.groups) > 3 and m.n_nodes > m.n_contour
    return m


def test_every_format_module_is_registered():
    """Adding a format is a module and its line in the registry: a module defining a
    FORMAT that the registry misses is caught here."""
    import importlib
    import pkgutil

    import deformesh_cli.formats as package

    defined = set()
    for info in pkgutil.iter_modules(package.__path__):
        module = importlib.import_module(f"deformesh_cli.formats.{info.name}")
        if hasattr(module, "FORMAT"):
            defined.add(module.FORMAT.name)
    assert defined == set(FORMATS)
    assert all(
        f.description and callable(f.render if f.sidecar else f.write) for f in FORMATS.values()
    )


@pytest.mark.parametrize("name", [n for n, f in FORMATS.items() if f.readable])
def test_round_trip(mesh, tmp_path, name):
    f = FORMATS[name]
    path = tmp_path / f"m.{name}"
    assert formats.write_mesh(mesh, str(path)) == name
    points, tri = formats.read_mesh(str(path), f.meshio_format)
    assert np.array_equal(points, mesh.points)  # every digit
    assert np.array_equal(tri, mesh.triangles)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        back = meshio.read(path, file_format=f.meshio_format)
    if f.point_data:
        assert np.array_equal(
            back.point_data["contour_point"][: mesh.n_contour], np.arange(mesh.n_contour)
        )
        assert (back.point_data["contour_point"][mesh.n_contour :] == -1).all()
    if f.boundary_groups:
        lines = np.concatenate([c.data for c in back.cells if c.type == "line"])
        assert sorted(map(tuple, lines.tolist())) == sorted(map(tuple, mesh.lines.tolist()))
        tags = np.concatenate(
            [d for c, d in zip(back.cells, next(iter(back.cell_data.values()))) if c.type == "line"]
        )
        assert len(np.unique(tags)) == len(mesh.groups)


@pytest.mark.parametrize("name", sorted(FORMATS))
def test_stdout_is_offered_exactly_where_the_format_says(mesh, name, capfdbinary):
    f = FORMATS[name]
    if f.stdout:
        formats.write_mesh(mesh, "-", name)
        assert len(capfdbinary.readouterr().out) > 1000
    else:
        with pytest.raises(OptionError, match="cannot go to stdout"):
            formats.write_mesh(mesh, "-", name)


@pytest.mark.parametrize("name", [n for n, f in FORMATS.items() if f.sidecar])
def test_a_sidecar_is_written_beside_its_file_and_listed_first(mesh, name):
    files = formats.mesh_files(mesh, f"m.{name}", name)
    assert [n for n, _ in files] == [f"m{FORMATS[name].sidecar}", f"m.{name}"]


def test_versions_are_checked(mesh, tmp_path):
    assert formats.MSH_VERSIONS[0] == "2.2"
    formats.write_mesh(mesh, str(tmp_path / "m.msh"), msh_version="4.1")
    assert (tmp_path / "m.msh").read_text().startswith("$MeshFormat\n4.1")
    with pytest.raises(OptionError, match="--msh-version"):
        formats.write_mesh(mesh, str(tmp_path / "n.msh"), msh_version="3.0")


@pytest.mark.parametrize("version", ["2.2", "4.1"])
@pytest.mark.parametrize("case", ["holes and extra nodes", "exterior box"])
def test_every_msh_reader_sees_node_k_as_point_k(tmp_path, version, case):
    """meshio, scikit-fem and gmsh read the nodes of our .msh in node order, with holes,
    extra boundary nodes (after every ring's points, on the outer ring's curve) and the
    box sides of an exterior mesh: node k is point k in all three."""
    import gmsh  # the test extra installs gmsh and scikit-fem
    import skfem

    from .conftest import contour_file

    c = load_contour(contour_file("square_hole_100.csv"))
    if case == "exterior box":
        mesh = mesh_contour(c, exterior=True).mesh
        assert mesh.n_box > 0
    else:
        mesh = mesh_contour(c, grid="uniform", max_nodes=2_000_000).mesh
        assert mesh.n_extra > 0 and len(mesh.groups) > 1
    path = tmp_path / "m.msh"
    formats.write_mesh(mesh, str(path), msh_version=version)
    m = meshio.read(path)
    assert np.array_equal(m.points[:, :2], mesh.points)
    assert np.array_equal(m.cells_dict["triangle"], mesh.triangles)
    assert np.array_equal(skfem.MeshTri.load(str(path)).p.T, mesh.points)
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(path))
        tags, xyz, _ = gmsh.model.mesh.getNodes()
    finally:
        gmsh.finalize()
    order = np.argsort(tags)
    assert np.array_equal(tags[order], np.arange(1, mesh.n_nodes + 1))
    assert np.array_equal(xyz.reshape(-1, 3)[order, :2], mesh.points)


def test_the_formats_page_table_says_what_the_registry_says():
    """docs/formats.md's table of what each file carries, row by row against the
    registry (a format's groups, point data, stdout, binary, read back)."""
    from pathlib import Path

    page = (Path(__file__).resolve().parents[1] / "docs" / "formats.md").read_text()
    head = "| extension | boundary groups | point data | to stdout | read back by"
    lines = page[page.index(head) :].splitlines()[2:]
    rows = {}
    for line in lines:
        if not line.startswith("| `."):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows[cells[0].strip("`.")] = cells[1:]
    assert set(rows) == set(FORMATS)
    for name, (groups, point_data, stdout, back) in rows.items():
        f = FORMATS[name]
        assert groups.startswith("yes") == f.boundary_groups, name
        assert point_data.startswith("yes") == f.point_data, name
        assert stdout.startswith("yes") == f.stdout, name
        assert ("not to a terminal" in stdout) == f.binary, name
        assert back.startswith("yes") == f.readable, name
