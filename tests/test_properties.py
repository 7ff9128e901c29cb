"""Property tests over random simple polygons.

Every random polygon either gives a mesh meeting the contract or is refused
with one of the documented errors; and meshing commutes with translation and
scaling by powers of two (the grid is laid relative to the contour).
"""

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from deformesh_cli import mesh_contour
from deformesh_cli.contour import make_contour
from deformesh_cli.geometry import signed_area, signed_areas
from deformesh_cli.quality import check_contract

MAX_NODES = 60_000  # keeps each example well under a second


@st.composite
def star_polygons(draw, r_min: float = 0.4, max_points: int = 40):
    """Simple polygons of 3 to ``max_points`` points: star-shaped around the origin with
    random angles and radii from ``r_min`` to 1 (0.1: corners down to a few degrees)."""
    n = draw(st.integers(3, max_points))
    gaps = np.array(draw(st.lists(st.floats(0.2, 1.0), min_size=n, max_size=n)))
    theta = 2 * np.pi * np.cumsum(gaps) / gaps.sum()
    r = np.array(draw(st.lists(st.floats(r_min, 1.0), min_size=n, max_size=n)))
    pts = np.column_stack([r * np.cos(theta), r * np.sin(theta)])
    if draw(st.booleans()):
        pts = pts[::-1]  # clockwise input too
    return pts


#: Found by hypothesis: a notch of the outside narrowing to a reflex corner, its
#: edges three points' spacing long; cells next to a point as large as its size let
#: the loop cut across the notch's tip and the deformation fold there.
NOTCH_EXAMPLE = np.array(
    [
        (0.980172488, 0.198146143),
        (0.460738106, 0.194217398),
        (0.826238774, 0.563320058),
        (0.698236818, 0.715866849),
        (0.542546264, 0.840025923),
        (0.365341024, 0.930873749),
        (0.173648178, 0.984807753),
        (-0.0249306917, 0.999689182),
        (-0.222520934, 0.974927912),
        (-0.411287103, 0.911505852),
        (-0.583743672, 0.811938006),
        (-0.733051872, 0.680172738),
        (-0.853290882, 0.521435203),
        (-0.939692621, 0.342020143),
        (-0.988830826, 0.149042266),
        (-0.998756921, -0.0498458857),
        (-0.969077286, -0.246757398),
        (-0.900968868, -0.433883739),
        (-0.797132507, -0.60380441),
        (-0.661685838, -0.749781203),
        (-0.5, -0.866025404),
        (-0.31848665, -0.947927346),
        (-0.124343705, -0.992239207),
        (0.0747300936, -0.997203797),
        (0.270840468, -0.962624247),
        (0.456210657, -0.889871809),
        (0.623489802, -0.781831482),
        (0.698236818, -0.715866849),
        (0.826238774, -0.563320058),
        (0.921476212, -0.388434796),
        (0.490086244, -0.0990730716),
        (1.0, -2.4492936e-16),
    ]
)


#: Found by hypothesis: the same with the notch's tip nearer the middle.
DEEP_NOTCH_EXAMPLE = np.array(
    [
        (0.977780162, 0.209632904),
        (0.912108091, 0.409949789),
        (0.402951116, 0.296024319),
        (0.663882341, 0.747837039),
        (0.492359733, 0.870391805),
        (0.298956818, 0.95426664),
        (0.0922683595, 0.995734176),
        (-0.118520475, 0.992951609),
        (-0.324042298, 0.946042594),
        (-0.515163787, 0.857091753),
        (-0.683391564, 0.730052033),
        (-0.821249642, 0.570569037),
        (-0.876814922, 0.480828028),
        (-0.922611652, 0.385730138),
        (-0.958129612, 0.286334849),
        (-0.996865334, 0.0791170425),
        (-0.991300683, -0.1316167),
        (-0.941682952, -0.336501439),
        (-0.850217136, -0.526432163),
        (-0.720967946, -0.692968413),
        (-0.559679175, -0.828709371),
        (-0.373518443, -0.927622754),
        (-0.170758672, -0.985312882),
        (0.0395895584, -0.999216026),
        (0.248178442, -0.968714334),
        (0.445738356, -0.895163291),
        (0.623489802, -0.781831482),
        (0.663882341, -0.747837039),
        (0.805902233, -0.592048639),
        (0.912108091, -0.409949789),
        (0.977780162, -0.209632904),
        (0.5, -1.2246468e-16),
    ]
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(star_polygons(), st.floats(-3, 3), st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)))
def test_every_valid_star_polygon_meets_the_contract(pts, log_scale, shift):
    pts = pts * 10.0**log_scale + np.array(shift)
    c = make_contour(pts, source="random")
    res = mesh_contour(c, max_nodes=MAX_NODES)  # (valid: a refusal fails)
    m = res.mesh
    check_contract(m, c)  # again, explicitly
    assert (signed_areas(m.points, m.triangles) > 0).all()
    assert np.array_equal(m.points[: c.n], c.points)
    assert abs(signed_areas(m.points, m.triangles).sum() - abs(signed_area(c.points))) <= (
        1e-10 * abs(signed_area(c.points))
    )


#: Found by hypothesis: a symmetric U-turn where a cell's diagonal is a tie up to
#: round-off (translated by -0.25 in y it must mesh the same way).
UTURN_TIE_EXAMPLE = np.array(
    [
        (0.49173085081687107, 0.09055810485492786),
        (0.4671969185803356, 0.1781208557947084),
        (0.6027233365912337, 0.4463458071140922),
        (0.6990124470078821, 0.7151095013548994),
        (0.5766803221148672, 0.816969893010442),
        (0.219867360502953, 0.449063852681848),
        (0.04546743115442356, 0.49792842126576564),
        (-0.13489838557851205, 0.4814586436738997),
        (-0.5951277428187896, 0.8036311154549783),
        (-0.8423706192694115, 0.5388986359155756),
        (-0.9790840876823228, 0.20345601305263403),
        (-0.9873296559154696, -0.15868254645625104),
        (-0.9422609221188205, -0.3348796121709861),
        (-0.8660254037844388, -0.4999999999999997),
        (-0.6990124470078823, -0.715109501354899),
        (-0.31554397216302615, -0.38785564535221007),
        (-0.5000000000000004, -0.8660254037844384),
        (-0.1447231953332005, -0.3795974963465227),
        (-0.08717600829016166, -0.3967863481504797),
        (0.05989512290584667, -0.40181044878411704),
        (0.11848116290352267, -0.38858882708722975),
        (0.5388986359155754, -0.8423706192694117),
        (0.8036311154549779, -0.5951277428187901),
        (0.9629172873477992, -0.2697967711570244),
        (0.5, -1.2246467991473532e-16),
    ]
)


#: Found by hypothesis: a polygon whose deformation folds in its first step where
#: the loop is far from its points; it must mesh, and the same after a translation.
FIRST_STEP_FOLD_EXAMPLE = np.array(
    [
        (0.8907401756824413, -2.1816842100429058e-16),
        (0.7792757255113362, -0.32650713692945543),
        (0.28629364625532916, -0.27934915090944606),
        (0.5938624199452842, -0.7249641485996212),
        (0.11877851459955173, -0.4310606675635238),
        (0.027861860742568037, -0.39902846604717535),
        (-0.047720971883281435, -0.6045930033488919),
        (-0.1367503315761659, -0.37589805375102525),
        (-0.16965142655861104, -0.36224079486803834),
        (-0.2037365366308777, -0.34422583232763787),
        (-0.5126015093889436, -0.6301454633261417),
        (-0.4066630563861202, -0.23612770841784225),
        (-0.9502888293967455, -0.31133766367685606),
        (-0.8891478890840392, 0.11518466131475362),
        (-0.37843338296249257, 0.22081402613800255),
        (-0.6889885456788288, 0.6083980703106903),
        (-0.40314103721139943, 0.8607659259510001),
        (-0.005850001983225878, 0.3999572195582876),
        (0.10667407716581388, 0.8768999334228719),
        (0.19685249131526722, 0.3482084098108095),
        (0.3246046487159916, 0.4475074455751979),
        (0.34284425719730083, 0.2870182049236908),
        (0.5189299381962551, 0.3390729548025441),
        (0.6485623575494474, 0.2025070669702027),
    ]
)


#: Found by hypothesis: a polygon whose deformation can carry a free node onto the
#: line through two path nodes (a triangle of area 1e-16 times the mean, its sign
#: round-off); the mesh must not hang on that sign, drawn or moved.
FLAT_TRIANGLE_EXAMPLE = np.array(
    [
        (0.6448992238680096, 0.15279822442904017),
        (0.4986205341393722, 0.27804132511713686),
        (0.7184256819576538, 0.6956037230375353),
        (0.3368194069702614, 0.41234777079752366),
        (0.3370167344460489, 0.6998365277142781),
        (0.36394840355367875, 0.87752011917148),
        (0.11553997941140325, 0.9932927631154939),
        (0.026582600267594694, 0.8400556852714501),
        (-0.028728163551313062, 0.5755253886219721),
        (-0.07331962977340362, 0.49459501806012063),
        (-0.17634126355270938, 0.5009481989917843),
        (-0.4669205724057683, 0.7050293482053958),
        (-0.4012560295076653, 0.4985570340620606),
        (-0.8168132057088796, 0.5769022334673212),
        (-0.509640286463024, 0.19024390180130127),
        (-0.7505965405168752, 0.12199713566098426),
        (-0.8361471938100913, -0.03993807022158903),
        (-0.9063394344204154, -0.20658637397161406),
        (-0.6169852835877431, -0.2526386888192938),
        (-0.7252258912815349, -0.4501043946493057),
        (-0.4928263115732378, -0.5428283450687694),
        (-0.3918228708242274, -0.4961936637525119),
        (-0.38546534144658273, -0.6642644550345482),
        (-0.29020415125758803, -0.7126633732236006),
        (-0.16252745955493791, -0.47284757046073317),
        (-0.07541794441362422, -0.6937080506483165),
        (-0.02605485972607235, -0.9996505111210892),
        (0.0915303442811145, -0.9957922454888775),
        (0.281015595861926, -0.9074856664886595),
        (0.281584129885889, -0.5628618286745571),
        (0.5764438914579733, -0.6911674471506803),
        (0.6252261733313369, -0.45136537623455064),
        (0.8551364159312294, -0.4481316573676456),
        (0.8315015243994895, -0.3677699507058954),
        (0.4040920265969073, -0.13557334180124528),
        (0.5243872288331849, -0.059689635481034196),
        (0.5622004430991212, -1.1363679968370878e-15),
    ]
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(star_polygons(), st.integers(-4, 4), st.integers(-50, 50), st.integers(-50, 50))
@example(UTURN_TIE_EXAMPLE, 0, 0, -1)
@example(FIRST_STEP_FOLD_EXAMPLE, 0, -33, -22)
@example(FLAT_TRIANGLE_EXAMPLE, 4, -46, -34)
@example(NOTCH_EXAMPLE, 0, 0, 0)
@example(DEEP_NOTCH_EXAMPLE, 0, 0, 0)
def test_translation_and_power_of_two_scaling_commute(pts, k, dx, dy):
    # selection, deformation and cutting; the quality stage (tests/test_improve.py)
    # takes decisions on floating-point near-ties, which a translation can tip
    base = make_contour(pts, source="a")
    moved = make_contour(pts * 2.0**k + np.array([dx, dy]) * 0.25, source="b")
    a = mesh_contour(base, max_nodes=MAX_NODES, improve=False)  # (valid: a refusal fails)
    b = mesh_contour(moved, max_nodes=MAX_NODES, improve=False)
    assert np.array_equal(a.mesh.triangles, b.mesh.triangles)
    assert np.allclose(
        a.mesh.points * 2.0**k + np.array([dx, dy]) * 0.25,
        b.mesh.points,
        atol=1e-9 * 2.0**k * (1 + abs(dx) + abs(dy)),
    )


# --- polygons with holes, at every scale and far from the origin (the CI profile runs
# at least 1,000 of these: see conftest.py)


def _star(draw, n_lo, n_hi, r_lo, r_hi):
    n = draw(st.integers(n_lo, n_hi))
    gaps = np.array(draw(st.lists(st.floats(0.5, 1.0), min_size=n, max_size=n)))
    theta = 2 * np.pi * np.cumsum(gaps) / gaps.sum() + draw(st.floats(0, 2 * np.pi))
    r = np.array(draw(st.lists(st.floats(r_lo, r_hi), min_size=n, max_size=n)))
    return np.column_stack([r * np.cos(theta), r * np.sin(theta)])


@st.composite
def polygons_with_holes(draw):
    """An outer star (radius 0.7-1) and 0-2 holes (radius 0.1-0.15, centred within 0.35 of
    the origin) that can touch neither it nor each other; any ring may be clockwise.

    With holes the outer ring has >= 10 points, so its edges stay >= 0.59 from the
    origin (the widest angular gap is 2 pi / 5.5), beyond the holes' reach of 0.5.
    """
    holes = draw(st.integers(0, 2))
    rings = [_star(draw, 10 if holes else 3, 16, 0.7, 1.0)]
    for k in range(holes):
        cx = 0.0 if holes == 1 else (-0.3 if k == 0 else 0.3)
        rings.append(_star(draw, 3, 8, 0.1, 0.15) + [cx, draw(st.floats(-0.05, 0.05))])
    rings = [r[::-1] if draw(st.booleans()) else r for r in rings]
    scale = 10.0 ** draw(st.floats(-6, 6))
    shift = np.array([draw(st.floats(-1e3, 1e3)), draw(st.floats(-1e3, 1e3))]) * scale
    return [r * scale + shift for r in rings]


# 250 examples, not the ci profile's 1,000: a ring with holes is the slowest kind to
# mesh, and the suite has 10 minutes on 2 cores
@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(polygons_with_holes())
def test_every_valid_polygon_with_holes_meets_the_contract(rings):
    starts = np.cumsum([0] + [len(r) for r in rings])[:-1]
    c = make_contour(np.concatenate(rings), source="random", ring_starts=starts)
    assert [c.is_hole(r) for r in range(c.n_rings)] == [False] + [True] * (len(rings) - 1)
    res = mesh_contour(c, max_nodes=MAX_NODES)  # (valid: a refusal fails)
    m = res.mesh
    check_contract(m, c)
    assert np.array_equal(m.points[: c.n], c.points)
    assert (signed_areas(m.points, m.triangles) > 0).all()
    assert m.groups[: c.n_rings] == ("contour",) + tuple(f"hole_{k}" for k in range(1, c.n_rings))
