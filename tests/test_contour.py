import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from deformesh_cli.contour import make_contour
from deformesh_cli.errors import InputError
from deformesh_cli.geometry import signed_area
from deformesh_cli.readers import load_contour, parse_csv

SQUARE = [(0, 0), (1, 0), (1, 1), (0, 1)]


def csv(rows, header="x,y"):
    return "\n".join([header] + [f"{x},{y}" for x, y in rows]) + "\n"


def test_header_comments_bom_crlf_and_closing_point():
    text = "\ufeff# a square\r\nx,y\r\n" + "".join(f"{x},{y}\r\n" for x, y in SQUARE + [(0, 0)])
    c = parse_csv(text, "sq.csv")
    assert c.n == 4
    assert np.array_equal(c.points, np.array(SQUARE, float))
    assert list(c.lines) == [3, 4, 5, 6]
    assert not c.clockwise


@pytest.mark.parametrize("sep", [",", ";", "\t", "  "])
def test_delimiters_without_header(sep):
    c = parse_csv("\n".join(f"{x}{sep}{y}" for x, y in SQUARE), "s")
    assert c.n == 4 and c.area == 1.0


def test_clockwise_is_reoriented_but_input_order_kept():
    cw = SQUARE[::-1]
    c = parse_csv(csv(cw), "cw.csv")
    assert c.clockwise
    assert np.array_equal(c.points, np.array(cw, float))  # node k stays input point k
    assert signed_area(c.ccw_points) > 0
    assert c.ccw_order[0] == 0


@pytest.mark.parametrize(
    "text, message",
    [
        ("", "empty"),
        ("x,y\n", "no points after the header"),
        ("a,b\n0,0\n1,0\n0,1\n", "must name columns x and y"),
        ("x,y\n0,0\n1,zero\n0,1\n", "line 3: y value 'zero' is not a number"),
        ("x,y\n0,0\n1,nan\n0,1\n", "line 3: point 1 has a non-finite coordinate"),
        ("x,y\n0,0\n1,inf\n0,1\n", "non-finite"),
        ("x,y\n0,0\n1,1\n", "fewer than 3 distinct points"),
        ("x,y\n0,0\n1,0\n1,0\n0,1\n", "point 2 (line 4) at (1, 0) repeats the previous point"),
        ("x,y\n0,0\n1,0\n2,0\n", "encloses no area"),
        ("x,y\n0,0\n1,0\n0,1\n", None),
        ("x,y\n0,0\n1\n0,1\n", "line 3: 1 field, but line 1 has 2"),
    ],
)
def test_bad_csv_messages(text, message):
    if message is None:
        assert parse_csv(text, "f.csv").n == 3
        return
    with pytest.raises(InputError) as e:
        parse_csv(text, "f.csv")
    assert str(e.value).startswith("f.csv")
    assert message in str(e.value)


@given(
    n=st.integers(3, 40),
    data=st.data(),
    header=st.booleans(),
    sep=st.sampled_from([",", ";", "\t", " "]),
)
def test_a_row_with_another_number_of_fields_is_refused_by_its_line(n, data, header, sep):
    """No field is ever dropped or invented: one ragged row anywhere names its line."""
    t = 2 * np.pi * np.arange(n) / n
    rows = [[f"{np.cos(a):.6f}", f"{np.sin(a):.6f}"] for a in t]
    bad = data.draw(st.integers(0, n - 1 if header else n - 2)) + (0 if header else 1)
    extra = data.draw(st.booleans())
    rows[bad] = [*rows[bad], "500"] if extra else rows[bad][:1]
    lines = (["x,y".replace(",", sep)] if header else []) + [sep.join(r) for r in rows]
    with pytest.raises(InputError) as e:
        parse_csv("\n".join(lines) + "\n", "f.csv")
    line = bad + 1 + header
    assert f"f.csv: line {line}: {3 if extra else 1} field" in str(e.value)
    assert "but line 1 has 2" in str(e.value)


def test_self_intersection_names_edges_and_place():
    bowtie = [(0, 0), (2, 2), (2, 0), (0, 2)]
    with pytest.raises(InputError) as e:
        parse_csv(csv(bowtie), "bow.csv")
    msg = str(e.value)
    assert "intersects itself near (1, 1)" in msg
    assert "point 0 (line 2)" in msg and "point 2 (line 4)" in msg


def test_touching_contour_is_refused():
    # a figure eight through (1, 1) twice
    pts = [(0, 0), (1, 1), (2, 0), (2, 2), (1, 1), (0, 2)]
    with pytest.raises(InputError, match="intersects itself"):
        make_contour(pts, source="eight")


def test_load_contour_file_errors(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_contour(tmp_path / "missing.csv")
    with pytest.raises(InputError, match="is a directory"):
        load_contour(tmp_path)
    b = tmp_path / "bin.csv"
    b.write_bytes(b"\x00\x01\x02garbage")
    with pytest.raises(InputError, match="binary file"):
        load_contour(b)
    s = tmp_path / "c.svg"
    s.write_text("<svg/>")
    with pytest.raises(InputError, match="no filled shape"):
        load_contour(s)


def test_min_spacing_is_over_all_pairs():
    # points 1 and 4 are close although not consecutive
    pts = [(0, 0), (1, 0), (1, 1), (0.55, 1), (0.5, 0.2), (0.45, 1), (0, 1)]
    c = make_contour(pts)
    d, a, b = c.min_spacing()
    assert d == pytest.approx(0.1)
    assert {a, b} == {3, 5}


def test_decimal_comma():
    text = "x;y\n0,0;0\n1,5;0\n1,5;2,25\n"
    c = parse_csv(text, "dc.csv", decimal=",")
    assert c.points.tolist() == [[0.0, 0.0], [1.5, 0.0], [1.5, 2.25]]
    # without --decimal ',' the same text is refused (a comma splits the fields)
    with pytest.raises(InputError):
        parse_csv(text, "dc.csv")


def test_decimal_comma_on_the_command_line(run, tmp_path):
    src = tmp_path / "dc.csv"
    src.write_text("0,0\t0\n1,5\t0\n1,5\t2,25\n0\t2,25\n")
    r = run("all", src, "--decimal", ",", "-o", tmp_path / "m.vtk", "--json")
    assert r.exit_code == 0, r.stderr
    r = run("all", src, "--decimal", ";", "-o", tmp_path / "n.vtk")
    assert r.exit_code == 2


def test_edge_lengths_stay_on_each_ring():
    text = "x,y,ring\n0,0,0\n4,0,0\n4,4,0\n0,4,0\n1,1,1\n1,2,1\n2,2,1\n"
    c = parse_csv(text, "t.csv")
    assert c.edge_lengths().tolist() == [4, 4, 4, 4, 1, 1, 2**0.5]


def test_resample_keeps_corners_and_evens_the_spacing():
    from deformesh_cli.contour import parse_spacing, resample

    # a square with crowded points on one side: corners are kept, chords even out
    side = [(x, 0.0) for x in (0, 0.001, 0.002, 0.5)] + [(1, 0), (1, 1), (0, 1)]
    c = make_contour(side, source="sq")
    r = resample(c, 0.1)
    for corner in [(0, 0), (1, 0), (1, 1), (0, 1)]:
        assert np.any(np.all(r.points == corner, axis=1)), corner
    e = r.edge_lengths()
    assert e.min() == pytest.approx(0.1) and e.max() == pytest.approx(0.1)
    assert r.area == pytest.approx(1.0)
    assert "resampled 7 points to 40" in r.notes[-1]
    assert parse_spacing("10%", c) == pytest.approx(np.sqrt(2) / 10)
    with pytest.raises(Exception, match="--resample"):
        parse_spacing("-1", c)


def test_resample_on_a_curve_stays_on_the_polyline():
    from deformesh_cli.contour import resample

    t = 2 * np.pi * np.arange(200) / 200
    c = make_contour(np.column_stack([np.cos(t), np.sin(t)]), source="c")
    r = resample(c, 0.1)
    rad = np.hypot(*r.points.T)
    assert rad.max() <= 1 + 1e-12 and rad.min() > 1 - 1e-3
    assert abs(r.n - 2 * np.pi / 0.1) <= 1


@pytest.mark.parametrize(
    "text, says",
    [
        ("x,y\n0,0\n1,zz\n1,0,3\n1,1\n", "line 3: y value 'zz'"),
        ("x,y\n0,0\n1,0,3\n1,zz\n1,1\n", "line 3: 3 fields"),
        ("x,y,ring\n0,0,0\n1,0,x\n1,1,0,9\n", "line 3: ring value 'x'"),
        ("x,y,ring\n0,0,0\n1,0,1.5\n1,qq,0\n", "line 3: ring value '1.5'"),
        ("x,y,ring\n0,0,0\n1,qq,1.5\n1,1,0\n", "line 3: y value 'qq'"),
        ("x,y\nzz,yy\n1,0\n1,1\n", "line 2: x value 'zz'"),
    ],
)
def test_a_csv_with_several_problems_names_the_first_in_the_files_order(text, says):
    """A row's fields are counted, then its x, y and ring read, row by row: the
    message names the first problem met that way."""
    with pytest.raises(InputError, match=says):
        parse_csv(text, "c.csv")
