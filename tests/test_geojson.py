"""GeoJSON contours (readers/geojson.py): polygons with holes, several parts, every
container type; other geometries and broken files refused in one line."""

import json
import re

import numpy as np
import pytest

from deformesh_cli.errors import InputError
from deformesh_cli.readers import load_contour

from .conftest import SAMPLES

SQUARE = [[0, 0], [4, 0], [4, 4], [0, 4], [0, 0]]
HOLE = [[1, 1], [1, 2], [2, 2], [2, 1], [1, 1]]  # clockwise, as RFC 7946 has holes
FAR = [[[6, 0], [8, 0], [8, 2], [6, 2], [6, 0]]]


def doc(kind: str) -> dict:
    polygon = {"type": "Polygon", "coordinates": [SQUARE, HOLE]}
    multi = {"type": "MultiPolygon", "coordinates": [[SQUARE, HOLE], FAR]}
    feature = {"type": "Feature", "properties": {"name": "x"}, "geometry": polygon}
    return {
        "Polygon": polygon,
        "MultiPolygon": multi,
        "Feature": feature,
        "FeatureCollection": {"type": "FeatureCollection", "features": [feature, {
            "type": "Feature", "properties": {}, "geometry": {"type": "Polygon",
                                                             "coordinates": FAR}}]},
        "GeometryCollection": {"type": "GeometryCollection", "geometries": [polygon, {
            "type": "Polygon", "coordinates": FAR}]},
    }[kind]  # fmt: skip


@pytest.mark.parametrize(
    "kind", ["Polygon", "MultiPolygon", "Feature", "FeatureCollection", "GeometryCollection"]
)
def test_every_container_gives_its_rings(tmp_path, kind):
    f = tmp_path / "c.geojson"
    f.write_text(json.dumps(doc(kind)))
    c = load_contour(f)
    parts = 1 if kind in ("Polygon", "Feature") else 2
    assert c.n_rings == 2 + (parts - 1)
    assert [c.is_hole(r) for r in range(c.n_rings)] == [False, True] + [False] * (parts - 1)
    # the closing repeat is dropped without a note, every point kept in order
    assert np.array_equal(c.points[:4], np.array(SQUARE[:4], dtype=float))
    assert not any("closing point" in n for n in c.notes)
    # RFC 7946's orientation (outer ring counter-clockwise, holes clockwise): no note
    assert not any("re-oriented" in n for n in c.notes), c.notes


def test_a_clockwise_outer_ring_is_noted_a_clockwise_hole_is_not(tmp_path):
    f = tmp_path / "c.geojson"
    f.write_text(json.dumps({"type": "Polygon", "coordinates": [SQUARE[::-1], HOLE]}))
    notes = [n for n in load_contour(f).notes if "re-oriented" in n]
    assert len(notes) == 1 and "outer ring" in notes[0]


def test_a_geojson_meshes_with_its_hole_and_its_parts(run, tmp_path):
    f = tmp_path / "c.json"  # (.json is read as GeoJSON too)
    f.write_text(json.dumps(doc("MultiPolygon")))
    r = run("all", f, "-o", tmp_path / "m.msh", "--json")
    assert r.exit_code == 0, r.stderr
    rep = json.loads(r.stdout)
    assert rep["contract"] == "ok" and rep["extra_boundary_nodes"] == 0
    assert rep["area"] == pytest.approx(16 - 1 + 4)


def test_a_third_coordinate_is_ignored(tmp_path):
    f = tmp_path / "c.geojson"
    f.write_text(json.dumps({"type": "Polygon", "coordinates": [[p + [100] for p in SQUARE]]}))
    assert np.array_equal(load_contour(f).points, np.array(SQUARE[:4], dtype=float))


@pytest.mark.parametrize(
    "text,message",
    [
        ('{"type": "LineString", "coordinates": [[0, 0], [1, 1]]}', "is a LineString"),
        (
            '{"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": '
            '{"type": "Point", "coordinates": [0, 0]}}]}',
            "feature 1 is a Point",
        ),
        (
            '{"type": "Polygon", "coordinates": [[[0, 0], [1, 0]',
            "line 1, column 52: not valid JSON",
        ),
        ('{"type": "Polygon", "coordinates": [[[0, 0], [1, "a"], [1, 1]]]}', "not two numbers"),
        ('{"type": "Polygon", "coordinates": [[[0, 0], [1], [1, 1]]]}', "position 1 has fewer"),
        ('{"type": "Blob"}', "unknown GeoJSON type 'Blob'"),
        ('{"features": []}', "no 'type'"),
        ('{"type": "FeatureCollection", "features": []}', "no Polygon or MultiPolygon"),
        ("[" * 5000 + "]" * 5000, "nested too deep|not a GeoJSON object"),
    ],
)
def test_bad_geojson_is_one_line_naming_the_place(run, tmp_path, text, message):
    f = tmp_path / "c.geojson"
    f.write_text(text)
    with pytest.raises(InputError, match=message):
        load_contour(f)
    r = run("all", f, "-o", tmp_path / "m.msh")
    assert r.exit_code == 1 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "c.geojson" in r.stderr and not (tmp_path / "m.msh").exists()


@pytest.mark.parametrize(
    "name,data,what",
    [
        ("part.dxf", b"0\nSECTION\n2\nHEADER\n", "DXF"),
        ("part.txt", b"  0\nSECTION\n  2\nENTITIES\n", "DXF"),
        ("coast.shp", b"\x00\x00\x27\x0a", "an ESRI shapefile"),
        ("m.msh", b"$MeshFormat\n2.2 0 8\n", "a Gmsh mesh"),
        ("scan.png", b"\x89PNG\r\n\x1a\n", "a PNG image"),
        ("m.vtu", b'<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid">', "a VTK mesh"),
    ],
)
def test_other_formats_are_named(run, tmp_path, name, data, what):
    f = tmp_path / name
    f.write_bytes(data)
    r = run("all", f, "-o", tmp_path / "m.vtk")
    assert r.exit_code == 1 and r.stderr.count("\n") == 1
    assert f"{what} is not a contour format deformesh reads" in r.stderr


def test_a_mesh_given_where_a_frame_belongs_is_named(run, tmp_path):
    """``move MESH FRAME``: a .vtu given as the frame (it starts with ``<``, as SVG
    does) is named, not parsed as SVG."""
    mesh = tmp_path / "m.vtu"
    r = run("all", SAMPLES / "circle.csv", "-o", mesh, "-q")
    assert r.exit_code == 0, r.stderr
    r = run("move", mesh, mesh, "--out-dir", tmp_path / "frames")
    assert r.exit_code == 1 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "m.vtu: a VTK mesh is not a contour format" in r.stderr
    assert not (tmp_path / "frames").exists() or not any((tmp_path / "frames").iterdir())


@pytest.mark.parametrize(
    "text,root",
    [
        (b"<html><body><p>a page</p></body></html>", "<html>"),
        (b'<?xml version="1.0"?>\n<!-- made by hand -->\n<VTKFile type="x"/>', "<VTKFile>"),
    ],
)
def test_an_xml_document_that_is_not_svg_is_named(run, tmp_path, text, root):
    f = tmp_path / "c.svg"
    f.write_bytes(text)
    r = run("all", f, "-o", tmp_path / "m.vtk")
    assert r.exit_code == 1 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert f"not an SVG document: its root element is {root}" in r.stderr


def test_a_real_coastline_with_a_hole_meshes_with_the_contract(run, tmp_path):
    """South Africa from Natural Earth: a mainland with Lesotho as a hole, and an island
    group, checked with numpy and shapely only."""
    import json

    import meshio

    from deformesh_cli.readers import load_contour

    from .conftest import ROOT
    from .independent import contract_problems

    f = ROOT / "tests" / "data" / "geojson" / "south_africa.geojson"
    r = run("all", f, "-o", tmp_path / "m.msh", "--json")
    assert r.exit_code == 0, r.stderr
    assert json.loads(r.stdout)["contract"] == "ok"
    c = load_contour(f)
    assert c.n_rings == 3 and sorted(c.depth) == [0, 0, 1]  # (the hole inside the mainland)
    m = meshio.read(tmp_path / "m.msh")
    assert contract_problems(m.points, m.cells_dict["triangle"], c.points, c.ring) == []


# --- roles, not nesting alone: RFC 7946's region (a polygon is its outer ring minus its
# holes, a MultiPolygon or a set of features the union of its polygons)

OUTER = [[0, 0], [3, 0], [3, 3], [0, 3], [0, 0]]
INNER = [[1, 1], [1, 2], [2, 2], [2, 1], [1, 1]]
ISLAND = [[1.2, 1.2], [1.8, 1.2], [1.8, 1.8], [1.2, 1.8], [1.2, 1.2]]


def _feature(coords):
    return {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon",
                                                               "coordinates": coords}}  # fmt: skip


@pytest.mark.parametrize(
    "geo",
    [
        {"type": "MultiPolygon", "coordinates": [[OUTER, INNER], [ISLAND]]},
        {"type": "FeatureCollection", "features": [_feature([OUTER, INNER]), _feature([ISLAND])]},
        {"type": "FeatureCollection", "features": [_feature([ISLAND]), _feature([OUTER, INNER])]},
    ],
)
def test_a_polygon_in_another_ones_hole_is_a_solid_of_its_own(run, tmp_path, geo):
    f = tmp_path / "c.geojson"
    f.write_text(json.dumps(geo))
    r = run("all", f, "-o", tmp_path / "m.vtk", "--json")
    assert r.exit_code == 0, r.stderr
    rec = json.loads(r.stdout)
    assert rec["contract"] == "ok"
    assert rec["area"] == pytest.approx(9 - 1 + 0.36, rel=1e-12)


@pytest.mark.parametrize(
    "geo, message",
    [
        (
            {"type": "Polygon", "coordinates": [OUTER, [[4, 0], [5, 0], [5, 1], [4, 1], [4, 0]]]},
            r"polygon hole 1 lies outside every ring \(its first position \(4, 0\)\)",
        ),
        (
            {"type": "Polygon", "coordinates": [[[0, 0], [5, 0], [5, 5], [0, 5], [0, 0]],
                                                [[1, 1], [1, 4], [4, 4], [4, 1], [1, 1]],
                                                [[2, 2], [2, 3], [3, 3], [3, 2], [2, 2]]]},
            r"polygon hole 2 lies inside polygon hole 1",
        ),
        (
            {"type": "MultiPolygon", "coordinates": [[OUTER], [INNER]]},
            r"polygon 2 outer ring lies inside polygon 1 outer ring .*overlap",
        ),
        (
            {"type": "FeatureCollection", "features": [_feature([OUTER]), _feature([INNER])]},
            r"feature 2 outer ring lies inside feature 1 outer ring .*overlap",
        ),
        (  # a hole of one polygon inside another polygon
            {"type": "MultiPolygon", "coordinates": [[OUTER], [[[5, 0], [6, 0], [6, 1], [5, 1],
                                                               [5, 0]], INNER]]},
            r"polygon 2 hole 1 lies inside polygon 1 outer ring",
        ),
    ],
)  # fmt: skip
def test_rings_whose_nesting_is_not_their_role_are_refused(run, tmp_path, geo, message):
    f = tmp_path / "c.geojson"
    f.write_text(json.dumps(geo))
    r = run("all", f, "-o", tmp_path / "m.vtk")
    assert r.exit_code == 1
    assert r.stderr.startswith(f"deformesh: error: {f}: ") and r.stderr.count("\n") == 1
    assert re.search(message, r.stderr), r.stderr
    assert not (tmp_path / "m.vtk").exists()
