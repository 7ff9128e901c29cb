"""SVG input: geometry (transforms, viewBox, y flip, flattening), fill rules, errors, pictures."""

import io
import json
import math

import numpy as np
import pytest
import shapely
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from deformesh_cli.errors import InputError, OptionError
from deformesh_cli.readers.svg import parse_svg

from .conftest import DATA, SAMPLES

SVG = '<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" {extra}>{body}</svg>'


def svg(body, w=100, h=100, extra=""):
    return SVG.format(w=w, h=h, extra=extra, body=body).encode()


def ring_points(c, r):
    return c.points[c.starts[r] : c.starts[r + 1]]


def test_polygon_is_flipped_and_keeps_its_vertices():
    c = parse_svg(svg('<polygon points="10,10 60,10 60,40 10,40"/>', h=100), "p.svg")
    # y -> 100 - y; the input order is kept (clockwise after the flip, walked ccw)
    assert c.points.tolist() == [[10, 90], [60, 90], [60, 60], [10, 60]]
    assert c.area == pytest.approx(50 * 30)


def test_without_height_or_viewbox_y_is_negated():
    body = '<polygon points="0,0 10,0 0,10"/>'
    c = parse_svg(
        SVG.format(w=0, h=0, extra="", body=body).replace('width="0" height="0" ', "").encode(),
        "n.svg",
    )
    assert c.points.tolist() == [[0, 0], [10, 0], [0, -10]]


def test_transforms_and_viewbox_are_applied():
    # viewBox 0 0 50 50 in a 100x100 viewport: everything doubles
    body = (
        '<g transform="translate(5 5)"><rect x="0" y="0" width="10" height="20" '
        'transform="scale(2 1)"/></g>'
    )
    c = parse_svg(svg(body, extra='viewBox="0 0 50 50"'), "t.svg")
    xy = c.points
    # user box x 5..25, y 5..25 -> viewport x 10..50, y 10..50 -> flipped y 50..90
    assert xy[:, 0].min() == pytest.approx(10) and xy[:, 0].max() == pytest.approx(50)
    assert xy[:, 1].min() == pytest.approx(50) and xy[:, 1].max() == pytest.approx(90)


@settings(max_examples=40, deadline=None)
@given(
    st.floats(-180, 180),
    st.floats(0.2, 3),
    st.floats(-50, 50),
    st.floats(-50, 50),
    st.integers(3, 12),
    st.integers(0, 10_000),
)
def test_random_polygon_under_random_transform_lands_where_the_matrix_says(
    angle, scale, tx, ty, n, seed
):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 2 * np.pi, n))
    assume(np.diff(np.concatenate([t, [t[0] + 2 * np.pi]])).min() > 1e-3)
    rad = rng.uniform(5, 20, n)
    pts = np.column_stack([50 + rad * np.cos(t), 50 + rad * np.sin(t)])
    assume(shapely.is_simple(shapely.LinearRing(pts)))
    body = (
        f'<polygon transform="translate({tx} {ty}) rotate({angle}) scale({scale})" '
        f'points="{" ".join(f"{float(x)!r},{float(y)!r}" for x, y in pts)}"/>'
    )
    c = parse_svg(svg(body, w=200, h=150), "r.svg")
    a = math.radians(angle)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    want = pts @ (scale * rot).T + [tx, ty]
    want[:, 1] = 150 - want[:, 1]
    assert c.n == n
    np.testing.assert_allclose(c.points, want, rtol=0, atol=1e-9 * (1 + np.abs(want).max()))


@pytest.mark.parametrize("tol", [0.05, 0.5, 2.0])
def test_circle_flattened_within_tolerance_with_points_on_the_circle(tol):
    c = parse_svg(svg('<circle cx="50" cy="50" r="30"/>'), "c.svg", tolerance=tol)
    p = c.points - [50, 50]
    np.testing.assert_allclose(np.hypot(p[:, 0], p[:, 1]), 30, rtol=1e-12)
    # sagitta of each chord: r - distance from the centre to the chord's midpoint
    mid = 0.5 * (p + np.roll(p, -1, axis=0))
    sag = 30 - np.hypot(mid[:, 0], mid[:, 1])
    assert sag.max() <= tol
    assert sag.max() > tol / 4  # not needlessly fine


def test_relative_tolerance_and_default_follow_the_drawing_size():
    small = parse_svg(svg('<circle cx="50" cy="50" r="30"/>'), "c.svg")
    big = parse_svg(svg('<circle cx="500" cy="500" r="300"/>', 1000, 1000), "c.svg")
    assert small.n == big.n  # the default is relative: same shape, same points
    pct = parse_svg(svg('<circle cx="50" cy="50" r="30"/>'), "c.svg", tolerance="1%")
    assert pct.n < small.n
    with pytest.raises(OptionError, match="--tolerance"):
        parse_svg(svg('<circle cx="50" cy="50" r="30"/>'), "c.svg", tolerance="-1")


def test_curve_endpoints_are_contour_points():
    d = "M 10 10 C 30 0 50 20 70 10 Q 80 40 70 70 A 30 30 0 0 1 10 70 Z"
    c = parse_svg(svg(f'<path d="{d}"/>'), "p.svg", tolerance=0.1)
    for x, y in [(10, 10), (70, 10), (70, 70), (10, 70)]:
        assert np.any(np.all(c.points == [x, 100 - y], axis=1)), (x, y)
    # the same path in relative commands gives the same points
    rel = "m 10 10 c 20 -10 40 10 60 0 q 10 30 0 60 a 30 30 0 0 1 -60 0 z"
    c2 = parse_svg(svg(f'<path d="{rel}"/>'), "p.svg", tolerance=0.1)
    np.testing.assert_allclose(c2.points, c.points, atol=1e-9)


SQUARE = "M 10 10 H 90 V 90 H 10 Z"
INNER_SAME = "M 30 30 H 70 V 70 H 30 Z"  # same direction as SQUARE
INNER_OPPOSITE = "M 30 30 V 70 H 70 V 30 Z"


@pytest.mark.parametrize(
    "rule,inner,holes",
    [
        ("evenodd", INNER_SAME, 1),
        ("evenodd", INNER_OPPOSITE, 1),
        ("nonzero", INNER_SAME, 0),  # winding 2 inside: filled, the inner ring is no boundary
        ("nonzero", INNER_OPPOSITE, 1),
    ],
)
def test_fill_rule_decides_holes(rule, inner, holes):
    c = parse_svg(svg(f'<path fill-rule="{rule}" d="{SQUARE} {inner}"/>'), "f.svg")
    assert c.n_rings == 1 + holes
    assert c.area == pytest.approx(80 * 80 - holes * 40 * 40)
    if not holes:
        assert any("dropped path 1 subpath 2" in n for n in c.notes)


def test_fill_rule_is_inherited_from_a_group():
    body = f'<g fill-rule="evenodd"><path d="{SQUARE} {INNER_SAME}"/></g>'
    assert parse_svg(svg(body), "g.svg").n_rings == 2


def test_island_in_a_hole_of_another_element_is_a_part():
    body = (
        f'<path id="frame" fill-rule="evenodd" d="{SQUARE} {INNER_SAME}"/>'
        '<circle id="dot" cx="50" cy="50" r="10"/>'
    )
    c = parse_svg(svg(body), "i.svg")
    assert [c.is_hole(r) for r in range(c.n_rings)] == [False, True, False]
    assert c.ring_labels[2] == "circle#dot subpath 1"


def test_overlapping_elements_of_one_paint_are_their_union():
    body = (
        '<rect id="a" x="10" y="10" width="50" height="50"/><circle id="b" cx="57" cy="35" r="10"/>'
    )
    c = parse_svg(svg(body), "o.svg")
    drawn = shapely.union(shapely.box(10, 40, 60, 90), shapely.Polygon(ring_points(c, 0)))
    assert c.n_rings == 1 and c.area == pytest.approx(drawn.area, rel=1e-12)
    assert 2500 + 90 < c.area < 2500 + math.pi * 100 / 2  # a cap 7 deep of r = 10
    assert any("touch or cross" in n and "2 crossing point(s)" in n for n in c.notes)
    # an element inside another of the same paint adds nothing
    inner = '<rect x="10" y="10" width="50" height="50"/><circle cx="35" cy="35" r="10"/>'
    c = parse_svg(svg(inner), "o.svg")
    assert c.n == 4 and c.area == 2500 and any("dropped circle" in n for n in c.notes)


def test_overlapping_elements_of_different_paint_are_refused_naming_both():
    body = (
        '<rect id="a" x="10" y="10" width="50" height="50"/>'
        '<circle id="b" cx="35" cy="35" r="10" fill="red"/>'
    )
    with pytest.raises(InputError, match=r"rect#a and circle#b overlap near .*fills.*--id"):
        parse_svg(svg(body), "o.svg")
    # --id picks one of them
    assert parse_svg(svg(body), "o.svg", element_id="b").n_rings == 1


def _star(evenodd):
    turn = [2 * math.pi * k * 2 / 5 for k in range(5)]
    tips = [(50 + 40 * math.sin(t), 50 - 40 * math.cos(t)) for t in turn]
    d = "M" + " L".join(f"{x!r} {y!r}" for x, y in tips) + " Z"
    rule = ' fill-rule="evenodd"' if evenodd else ""
    return svg(f'<path d="{d}"{rule}/>')


def test_self_crossing_subpath_is_meshed_as_filled():
    """A pentagram: nonzero fills the star (five tips and the five crossings), evenodd
    leaves the middle empty, five triangles meeting at points: refused where."""
    c = parse_svg(_star(False), "s.svg")
    assert c.n == 10 and c.n_rings == 1
    r = 40 * math.sin(math.radians(18)) / math.sin(math.radians(126))  # inner radius
    assert c.area == pytest.approx(5 * 40 * r * math.sin(math.radians(36)), rel=1e-12)
    assert np.allclose(np.sort(np.hypot(*(c.points - [50, 50]).T))[:5], r)
    with pytest.raises(InputError, match=r"pinches to a point at \(.*\), where path 1 subpath 1"):
        parse_svg(_star(True), "s.svg")


def test_subpaths_sharing_an_edge_are_one_region():
    c = parse_svg(svg('<path d="M10 10 H20 V20 H10 Z M20 10 H30 V20 H20 Z"/>'), "e.svg")
    assert c.n_rings == 1 and c.area == pytest.approx(200)
    # the shared edge's ends are given points on the boundary: kept
    assert {(20.0, 90.0), (20.0, 80.0)} <= set(map(tuple, c.points.tolist()))
    assert c.n == 6


def test_hole_touching_its_outline_is_refused_at_the_point():
    body = '<path d="M10 10 H50 V50 H10 Z M10 30 L30 20 L30 40 Z" fill-rule="evenodd"/>'
    with pytest.raises(
        InputError, match=r"t.svg: the filled area pinches to a point at \(10, 70\)"
    ):
        parse_svg(svg(body), "t.svg")


def test_rings_apart_come_out_as_given():
    body = '<path d="M10 10 H50 V50 H10 Z M20 20 V40 H40 V20 Z"/>'
    c = parse_svg(svg(body), "a.svg")
    assert c.points.tolist() == [[10, 90], [50, 90], [50, 50], [10, 50],
                                 [20, 80], [20, 60], [40, 60], [40, 80]]  # fmt: skip
    assert c.ring_labels == ("path 1 subpath 1", "path 1 subpath 2")


@settings(max_examples=25, deadline=None, derandomize=True)
@given(
    st.lists(
        st.tuples(st.floats(20, 80), st.floats(20, 80), st.floats(3, 25)), min_size=2, max_size=6
    )
)
def test_overlapping_circles_in_one_path_mesh_their_union(circles):
    """Circles drawn as polygons in one path, overlapping at random: the contour bounds
    exactly their union (shapely's, on the same polygons), nonzero rule."""
    rings = [
        [(x + r * math.cos(t), y + r * math.sin(t)) for t in np.linspace(0, 2 * math.pi, 24)[:-1]]
        for x, y, r in circles
    ]
    d = " ".join("M" + " L".join(f"{px!r} {py!r}" for px, py in ring) + " Z" for ring in rings)
    c = parse_svg(svg(f'<path d="{d}"/>'), "c.svg", tolerance=1e-9)
    union = shapely.union_all([shapely.Polygon([(px, 100 - py) for px, py in r]) for r in rings])
    assert c.area == pytest.approx(union.area, rel=1e-9)
    mine = shapely.union_all(
        [shapely.Polygon(ring_points(c, r)) for r in range(c.n_rings) if not c.is_hole(r)]
    )
    for r in range(c.n_rings):
        if c.is_hole(r):
            mine = mine.difference(shapely.Polygon(ring_points(c, r)))
    assert mine.symmetric_difference(union).area <= 1e-9 * union.area


def test_unfilled_and_hidden_shapes_are_skipped():
    body = (
        '<rect x="10" y="10" width="20" height="20" fill="none" stroke="black"/>'
        '<defs><circle id="c" cx="5" cy="5" r="3"/></defs>'
        '<polygon points="50,50 90,50 70,90"/>'
    )
    c = parse_svg(svg(body), "u.svg")
    assert c.n_rings == 1 and c.n == 3
    with pytest.raises(InputError, match="no filled shape"):
        parse_svg(svg('<rect width="5" height="5" fill="none"/>'), "u.svg")


@pytest.mark.parametrize(
    "data,text",
    [
        (b"<svg><polygon points='0,0 1,0", "not a readable SVG file"),
        (svg('<polygon points="0,0 10,10 10,0 0,10"/>'), r"pinches to a point at \(5, 95\)"),
        (svg('<polygon points="0,0 10,0 20,0"/>'), "skipped|no filled area"),
    ],
)
def test_bad_svg_is_one_line(data, text):
    with pytest.raises(InputError, match=text) as e:
        parse_svg(data, "bad.svg")
    assert "\n" not in str(e.value)


def test_self_intersection_names_the_element():
    with pytest.raises(InputError, match=r"polygon#bow subpath 1"):
        parse_svg(svg('<polygon id="bow" points="0,0 10,10 10,0 0,10"/>'), "bad.svg")


def test_cli_id_errors(run, tmp_path):
    f = tmp_path / "a.svg"
    f.write_bytes(svg('<rect id="a" x="10" y="10" width="50" height="50"/>'))
    r = run("all", f, "-o", tmp_path / "m.vtk", "--id", "nope")
    assert r.exit_code == 2 and "no element with id 'nope'; ids: a" in r.stderr
    assert not (tmp_path / "m.vtk").exists()
    c = tmp_path / "c.csv"
    c.write_text("0,0\n1,0\n0,1\n")
    r = run("all", c, "-o", tmp_path / "m.vtk", "--tolerance", "1")
    assert r.exit_code == 2 and "SVG input only" in r.stderr
    bad = tmp_path / "b.svg"
    bad.write_text("<svg><rect")
    r = run("all", bad, "-o", tmp_path / "m.vtk")
    assert r.exit_code == 1 and r.stderr.startswith("deformesh: error: ")
    assert r.stderr.count("\n") == 1 and not (tmp_path / "m.vtk").exists()


def test_svg_from_stdin_is_sniffed(run, tmp_path):
    data = svg('<polygon points="10,10 60,10 35,50"/>').decode()
    out = tmp_path / "m.vtk"
    r = run("all", "-", "-o", out, "--json", input=data)
    assert r.exit_code == 0, r.stderr
    assert json.loads(r.stdout)["contract"] == "ok"


# --- the sample: curves, a transform, a hole; its picture against an independent renderer


def test_sample_svg_meshes_with_the_contract(run, tmp_path):
    out = tmp_path / "b.msh"
    r = run("all", SAMPLES / "bracket.svg", "-o", out, "--json")
    assert r.exit_code == 0, r.stderr
    rec = json.loads(r.stdout)
    assert rec["contract"] == "ok"
    assert '"hole_1"' in out.read_text()
    r = run("quality", out, "--contour", SAMPLES / "bracket.svg", "--json")
    assert r.exit_code == 0, r.stdout
    assert json.loads(r.stdout)["contract"] == "ok"


def _disagreement(src, mesh_file, zoom):
    """resvg's rendering of ``src`` against our mesh rasterised on the same pixels:
    ``(painted, ours, far)``, ``far`` the pixels where they disagree farther than 1.5
    pixels from the mesh's boundary (anti-aliasing and the chord tolerance live nearer)."""
    import matplotlib.image as mpimg
    import meshio
    import resvg_py

    png = bytes(resvg_py.svg_to_bytes(svg_path=str(src), background="#ffffff", zoom=zoom))
    img = mpimg.imread(io.BytesIO(png), format="png")
    painted = img[..., :3].mean(axis=2) < 0.5
    m = meshio.read(mesh_file)
    domain = shapely.union_all(shapely.polygons(m.points[:, :2][m.cells_dict["triangle"]]))
    height = img.shape[0] / zoom  # the viewport height, which the y flip used
    i, j = np.mgrid[: img.shape[0], : img.shape[1]]
    x, y = (j + 0.5) / zoom, height - (i + 0.5) / zoom
    ours = shapely.contains_xy(domain, x, y)
    off = painted != ours
    near = shapely.dwithin(domain.boundary, shapely.points(x[off], y[off]), 1.5 / zoom)
    return painted, ours, int((~near).sum())


def test_sample_svg_mesh_covers_what_resvg_paints(run, tmp_path):
    """Rasterise our mesh and resvg's rendering of the SVG; they must agree pixel for pixel
    except along the edges (chord tolerance, anti-aliasing)."""
    src = SAMPLES / "bracket.svg"
    out = tmp_path / "b.vtk"
    assert run("all", src, "-o", out, "-q").exit_code == 0
    painted, ours, far = _disagreement(src, out, 4)
    iou = (painted & ours).sum() / (painted | ours).sum()
    assert painted.sum() > 0.2 * painted.size
    assert iou > 0.99, iou
    assert far == 0


OPEN_ICONS = DATA / "open_icons"


@pytest.mark.parametrize(
    "name",
    ["square", *sorted(p.stem for p in OPEN_ICONS.glob("*.svg"))],
)
def test_open_subpaths_are_filled_as_svg_fills_them(run, tmp_path, name):
    """A subpath without Z is closed by a straight edge, as a renderer fills it: the mesh
    covers what resvg paints, to the pixels along the edges, with a note."""
    if name == "square":
        src = tmp_path / "square.svg"
        src.write_text(
            '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 24 24">'
            '<path d="M2 2 L22 2 L22 22 L2 22"/></svg>'
        )
    else:
        src = OPEN_ICONS / f"{name}.svg"
    out = tmp_path / "m.vtk"
    r = run("all", src, "-o", out, "--strict", "--json")
    assert r.exit_code == 0, r.stderr
    assert json.loads(r.stdout)["contract"] == "ok"
    assert "as SVG fills it: a straight edge from its end" in r.stderr
    painted, ours, far = _disagreement(src, out, 16)
    assert painted.sum() > 0.05 * painted.size
    assert far == 0, far


@pytest.mark.parametrize(
    "body",
    [
        '<path d="M2 2 L22 22"/>',  # an open line: nothing to fill
        '<path d="M2 2 L22 2 L22 22 L2 22" fill="none" stroke="black"/>',  # not filled
    ],
)
def test_svg_with_nothing_a_renderer_fills_is_refused(run, tmp_path, body):
    src = tmp_path / "nothing.svg"
    src.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 24 24">{body}</svg>')
    r = run("all", src, "-o", tmp_path / "m.vtk")
    assert r.exit_code == 1
    assert r.stderr.startswith(f"deformesh: error: {src}: ") and r.stderr.count("\n") == 1
    assert not (tmp_path / "m.vtk").exists()


# --- real icons: matplotlib's toolbar SVGs (installed with the test extra, never downloaded)


def _mpl_icon(name):
    from pathlib import Path

    import matplotlib

    return Path(matplotlib.get_data_path()) / "images" / f"{name}.svg"


@pytest.mark.parametrize("name", ["help", "move", "zoom_to_rect", "subplots"])
def test_real_icons_mesh_with_the_contract(run, tmp_path, name):
    out = tmp_path / "m.vtk"
    r = run("all", _mpl_icon(name), "-o", out, "--json")
    assert r.exit_code == 0, r.stderr
    assert json.loads(r.stdout)["contract"] == "ok"
    r = run("quality", out, "--contour", _mpl_icon(name))
    assert r.exit_code == 0 and r.stdout.endswith("contract: ok\n")


def test_real_icon_with_overlapping_shapes_is_refused_by_name(run, tmp_path):
    r = run("all", _mpl_icon("hand"), "-o", tmp_path / "m.vtk")
    assert r.exit_code == 1
    assert "path#path51 and path#path124 overlap near" in r.stderr
    assert not (tmp_path / "m.vtk").exists()


MEETING_ICONS = DATA / "meeting_icons"


@pytest.mark.parametrize(
    "name", sorted(p.stem for p in MEETING_ICONS.glob("*.svg") if not p.stem.startswith("pinch"))
)
def test_icons_whose_subpaths_meet_mesh_what_resvg_paints(run, tmp_path, name):
    src = MEETING_ICONS / f"{name}.svg"
    out = tmp_path / "m.vtk"
    r = run("all", src, "-o", out, "--strict")
    assert r.exit_code == 0, r.stderr
    assert "touch or cross" in r.stderr or "the same ring as" in r.stderr
    painted, ours, far = _disagreement(src, out, 16)
    assert (painted & ours).sum() / (painted | ours).sum() > 0.97
    assert far == 0


def test_icon_pinched_to_a_point_is_refused_where(run, tmp_path):
    r = run("all", MEETING_ICONS / "pinch-si-printables.svg", "-o", tmp_path / "m.vtk")
    assert r.exit_code == 1
    assert r.stderr.count("\n") == 1 and "pinches to a point at (12, 4.8)" in r.stderr
    assert "pinch-si-printables.svg" in r.stderr and not (tmp_path / "m.vtk").exists()


def test_nearly_closed_subpath_is_closed_within_the_tolerance():
    # minified icons: the last point rounds to 0.001 from the first, no Z
    body = '<path d="M10 10 L20 10 L20 20 L10 20 L10.001 10.001"/>'
    c = parse_svg(svg(body), "n.svg")
    assert c.n == 4 and any("closed subpath 1" in n for n in c.notes)
    # with a finer tolerance it is closed as SVG fills it: by a straight edge
    c = parse_svg(svg(body), "n.svg", tolerance=1e-4)
    assert c.n == 5 and any("as SVG fills it" in n for n in c.notes)


def test_vertices_closer_than_the_tolerance_are_merged():
    # bootstrap-icons' star: the last vertex lands 0.001 from the first (rounded), with Z
    body = '<path d="M10 10 L20 10 L20 20 L10 20 L10 10.001 Z"/>'
    c = parse_svg(svg(body), "m.svg")
    assert c.n == 4 and any("merged 1 point(s)" in n for n in c.notes)
    e = c.edge_lengths()
    assert e.min() == pytest.approx(10.0)
    # with a finer tolerance the vertex stays
    assert parse_svg(svg(body), "m.svg", tolerance=1e-4).n == 5


@settings(max_examples=20, deadline=None)
@given(
    radius=st.floats(10, 30),
    step=st.floats(0.02, 0.4),
    tol=st.floats(0.1, 1.0),
)
def test_a_dense_run_of_vertices_moves_the_outline_by_at_most_the_tolerance(radius, step, tol):
    """A bump drawn in steps shorter than the tolerance keeps its shape: every vertex of
    the drawing is within the tolerance of the contour, and the area moves by at most
    twice the tolerance times the bump's length (losing the bump would move it more)."""
    assume(step < tol)
    n = max(3, int(math.pi * radius / step))
    t = np.linspace(0.0, np.pi, n)
    bump = np.c_[50 + radius * np.cos(t), 100 + radius * np.sin(t)]
    drawing = np.vstack([[(0, 0), (100, 0), (100, 100)], bump, [(0, 100)]])
    d = "M " + " L ".join(f"{x:.6f} {y:.6f}" for x, y in drawing) + " Z"
    c = parse_svg(svg(f'<path d="{d}"/>'), "bump.svg", tolerance=tol)
    ring = shapely.LinearRing(c.points * [1, -1] + [0, 100])  # (the reader flips y)
    drawn = shapely.Polygon(drawing)
    assert max(ring.distance(shapely.points(drawing))) <= tol * (1 + 1e-9)
    assert abs(shapely.Polygon(ring).area - drawn.area) <= 2 * tol * np.pi * radius
    assert np.pi * radius**2 / 2 > 2 * tol * np.pi * radius  # (so the test can fail)


def test_the_mesh_of_a_dense_drawing_has_the_drawing_s_area(run, tmp_path):
    """The whole way: the mesh of a drawing with a dense bump has the drawing's area."""
    t = np.linspace(0.0, np.pi, 400)
    bump = np.c_[50 + 20 * np.cos(t), 100 + 20 * np.sin(t)]  # steps of 0.16
    drawing = np.vstack([[(0, 0), (100, 0), (100, 100)], bump, [(0, 100)]])
    d = "M " + " L ".join(f"{x:.6f} {y:.6f}" for x, y in drawing) + " Z"
    f = tmp_path / "bump.svg"
    f.write_bytes(svg(f'<path d="{d}"/>'))
    r = run("all", f, "-o", tmp_path / "m.vtk", "--tolerance", "0.5", "--json")
    assert r.exit_code == 0, r.stderr
    area = json.loads(r.stdout)["area"]
    drawn = shapely.Polygon(drawing)
    assert abs(area - drawn.area) <= 2 * 0.5 * np.pi * 20 < 20**2 * np.pi / 2


# --- stroked shapes (--stroke): the outline the stroke paints

STROKE_ICONS = SAMPLES.parent / "tests" / "data" / "stroke_icons"


@pytest.mark.parametrize(
    "cap,join,area",
    [
        ("butt", "miter", 19 + 1),  # (an L: two bars overlapping in 1, the mitred corner)
        ("square", "miter", 19 + 1 + 2 * 2),
        ("round", "round", 19 + np.pi / 4 + np.pi),
        ("butt", "bevel", 19 + 0.5),
    ],
)
def test_a_stroke_paints_its_width_caps_and_joins(cap, join, area):
    """An L of width 2 (legs 6 and 4 from the corner): each cap and join adds what
    SVG paints; round parts are within the tolerance."""
    body = (
        '<path d="M 2 2 L 8 2 L 8 6" fill="none" stroke="black" stroke-width="2" '
        f'stroke-linecap="{cap}" stroke-linejoin="{join}"/>'
    )
    c = parse_svg(svg(body), "l.svg", tolerance=0.001, stroke=True)
    assert c.n_rings == 1
    assert shapely.Polygon(c.points).area == pytest.approx(area, rel=2e-3)


def test_strokes_that_cross_are_one_region_with_its_holes():
    """Two stroked squares overlapping: their union, with the holes it leaves."""
    body = "".join(
        f'<rect x="{x}" y="{x}" width="40" height="40" fill="none" stroke="red" stroke-width="4"/>'
        for x in (10, 30)
    )
    c = parse_svg(svg(body), "two.svg", stroke=True)
    holes = [label for label in c.ring_labels if "hole" in label]
    assert c.n_rings == 4 and len(holes) == 3  # (each square's hole, cut in two by the other)
    assert any("2 stroked SVG shape(s)" in n for n in c.notes)


@pytest.mark.parametrize("name", sorted(p.name for p in STROKE_ICONS.glob("*.svg")))
def test_stroked_line_icons_mesh_with_the_contract(run, tmp_path, name):
    from .independent import contract_problems

    f = STROKE_ICONS / name
    r = run("all", f, "--stroke", "-o", tmp_path / "m.msh", "--json")
    assert r.exit_code == 0, r.stderr
    assert json.loads(r.stdout)["contract"] == "ok"
    c = parse_svg(f.read_bytes(), name, stroke=True)
    import meshio

    m = meshio.read(tmp_path / "m.msh")
    assert contract_problems(m.points, m.cells_dict["triangle"], c.points, c.ring) == []
    # without --stroke the icon has nothing filled, and says how to mesh it
    r = run("all", f, "-o", tmp_path / "n.msh")
    assert r.exit_code == 1 and "give --stroke" in r.stderr
