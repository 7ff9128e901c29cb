"""A catalogue of hostile contour files, several per class: each is one line on stderr
naming the file (and the place), exit 1, no traceback, no file in the output folder,
an answer within a few seconds."""

import gzip
import re
import time

import numpy as np
import pytest

from .conftest import SAMPLES

pytestmark = pytest.mark.filterwarnings("error")  # (no numpy warning may leak either)

CIRCLE = SAMPLES / "circle.csv"
SVG = '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">{}</svg>'


def _level(k: int) -> str:
    return f'<g id="a{k}">' + f'<use href="#a{k - 1}"/>' * 10 + "</g>"


CASES = {
    # numbers at the edge of double precision
    "side-2e160.csv": (b"0,0\n2e160,0\n2e160,2e160\n0,2e160\n", "beyond 1e\\+150"),
    "side-2e300.csv": (b"0,0\n2e300,0\n2e300,2e300\n0,2e300\n", "beyond 1e\\+150"),
    "far-offset.csv": (  # (1 at 1e15: eight units in the last place across)
        b"1000000000000000,0\n1000000000000001,0\n1000000000000001,1\n",
        "below the coordinates' resolution",
    ),
    "side-1e-160.csv": (b"0,0\n1e-160,0\n1e-160,1e-160\n0,1e-160\n", "would underflow"),
    "nan.csv": (b"0,0\nnan,0\n1,1\n", "line 2: x value 'nan'|not finite|non-finite"),
    # ring ids that are not whole numbers a double holds
    "ring-1e19.csv": (b"x,y,ring\n0,0,1e19\n1,0,1e19\n1,1,1e19\n", "line 2: ring value '1e19'"),
    "ring-1e400.csv": (b"x,y,ring\n0,0,1e400\n1,0,1e400\n1,1,1e400\n", "ring value '1e400'"),
    "ring-inf.csv": (b"x,y,ring\n0,0,inf\n1,0,inf\n1,1,inf\n", "ring value 'inf'"),
    "ring-half.csv": (b"x,y,ring\n0,0,1.5\n1,0,1.5\n1,1,1.5\n", "ring value '1.5'"),
    # SVG that is not what it claims
    "no-moveto.svg": (
        SVG.format('<path d="L 1 1 L 5 1 L 5 5 Z"/>').encode(),
        "path 1: path data does not start with a moveto",
    ),
    "scale-1e300.svg": (
        SVG.format('<path transform="scale(1e300)" d="M 1 1 L 5 1 L 5 5 Z"/>').encode(),
        "beyond 1e\\+150",
    ),
    "curve-1e308.svg": (
        SVG.format('<path d="M 1 1 C 1e308 1 5 5 5 1 Q 3 -1e308 1 1 Z"/>').encode(),
        "beyond 1e\\+150",
    ),
    "html.svg": (b"<html><body><p>a page</p></body></html>", "root element is <html>"),
    "truncated.svgz": (
        gzip.compress(SVG.format('<path d="M 1 1 L 5 1 L 5 5 Z"/>').encode())[:30],
        "not a readable gzip-compressed SVG",
    ),
    # <use> references that multiply, cycle or nest deep (no hang, no recursion error)
    "use-bomb.svg": (  # (ten uses of the level below, nine levels: 10**9 paths)
        SVG.format(
            '<path id="a0" d="M 0 0 L 1 0 L 1 1 Z"/>' + "".join(map(_level, range(1, 10)))
        ).encode(),
        "references expand to over 10,000 elements",
    ),
    "use-cycle.svg": (
        SVG.format('<g id="a"><use href="#b"/></g><g id="b"><use xlink:href="#a"/></g>')
        .replace("<svg ", '<svg xmlns:xlink="http://www.w3.org/1999/xlink" ')
        .encode(),
        "references form a cycle",
    ),
    "use-chain.svg": (
        SVG.format(
            '<path id="a0" d="M 0 0 L 1 0 L 1 1 Z"/>'
            + "".join(f'<g id="a{k}"><use href="#a{k - 1}"/></g>' for k in range(1, 40))
        ).encode(),
        "nest deeper than 16",
    ),
    "nested-5000.svg": (
        SVG.format("<g>" * 5000 + '<path d="M 1 1 L 5 1 L 5 5 Z"/>' + "</g>" * 5000).encode(),
        "nest too deep",
    ),
    # coordinates whose scales no grid holds, numbers too long to convert
    "scales-1e9-1e-9.csv": (
        b"0,0\n1e9,0\n1e9,1e-9\n1e9,2e-9\n0,1e9\n",
        "point 1 at \\(1e\\+09, 0\\): its edge to the next point is 1e-09 long.*resolution",
    ),
    "scales-offset-1e-9.csv": (
        b"0,0\n1e9,0\n1e9,1e9\n1e-9,1e9\n1e-9,1e-9\n",
        "point 4 .* below the coordinates' resolution",
    ),
    "int-5000-digits.geojson": (
        b'{"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [1, 1], ['
        + b"1" * 5000
        + b", 0], [0, 0]]]}",
        "position 3 is not finite",
    ),
    # SVG in encodings deformesh does not read; text that would break the line
    "encoding-klingon.svg": (
        b'<?xml version="1.0" encoding="x-klingon"?>\n' + SVG.format("").encode(),
        "declares the encoding 'x-klingon'; deformesh reads SVG in UTF-8",
    ),
    "encoding-utf32.svg": (
        b"<?xml version='1.0' encoding='UTF-32'?>" + SVG.format("").encode(),
        "declares the encoding 'UTF-32'",
    ),
    "id-newline.svg": (
        SVG.format(
            '<path id="a&#10;deformesh: error: fake&#155;2J" d="M 1 1 L 5 5 L 5 1 L 1 5 Z"/>'
        ).encode(),
        r"a\\ndeformesh: error: fake\\x9b2J",
    ),
    # other programs' files given as contours
    "mesh.vtu": (b'<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid">', "a VTK mesh"),
    "lines.geojson": (b'{"type": "LineString", "coordinates": [[0, 0], [1, 1]]}', "LineString"),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_hostile_contour_is_one_line_and_leaves_nothing(run, tmp_path, name):
    data, message = CASES[name]
    f = tmp_path / name
    f.write_bytes(data)
    out = tmp_path / "out"
    out.mkdir()
    t = time.perf_counter()
    r = run("all", f, "-o", out / "m.msh", "--png", out / "m.png")
    assert time.perf_counter() - t < 30  # (a bound, not a benchmark: no hang)
    assert r.exit_code == 1, r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert r.stderr.startswith(f"deformesh: error: {f}:")
    assert re.search(message, r.stderr), r.stderr
    assert list(out.iterdir()) == []


@pytest.mark.parametrize(
    "args",
    [
        ("all", "/dev/zero", "-o"),
        ("deform", "/dev/zero", "-o"),
        ("triangulate", "/dev/urandom", "-o"),
    ],
)
def test_a_device_is_refused_not_read_forever(run, tmp_path, args):
    out = tmp_path / "out"
    out.mkdir()
    t = time.perf_counter()
    r = run(*args, out / "m.msh")
    assert time.perf_counter() - t < 30
    assert r.exit_code == 1, r.stderr
    assert r.stderr == f"deformesh: error: {args[1]}: is a character device, not a file\n"
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("kind", ["structured", "complex", "object-free bytes"])
def test_a_size_field_of_anything_but_real_numbers_is_one_line(run, tmp_path, kind):
    import numpy as np

    rows = np.array([[x, y, 1.0] for x in (-2.0, 2.0) for y in (-2.0, 2.0)])
    f = tmp_path / "f.npy"
    if kind == "structured":
        np.save(f, rows.view([("x", "f8"), ("y", "f8"), ("f", "f8")]).ravel())
    elif kind == "complex":
        np.save(f, rows.astype(complex))
    else:
        np.save(f, np.array([b"1,2,3"] * 4))
    out = tmp_path / "out"
    out.mkdir()
    r = run("all", CIRCLE, "-o", out / "m.vtk", "--size-field", f)
    assert r.exit_code == 1, r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert r.stderr.startswith(f"deformesh: error: {f}: a size field holds real numbers")
    assert list(out.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize(
    "args, message",
    [
        (["--max-h", "1e-4"], "needs at least"),
        (["--max-h", "3e-4", "--max-nodes", "100000"], "needs at least"),
        (["--max-h", "1e-6"], "needs at least"),
        (["--max-h", "1e-20"], "needs at least"),
        (["--resample", "1e-300"], "would give about"),
    ],
)
def test_memory_guards_refuse_before_the_memory_is_taken(sh, tmp_path, args, message):
    """Whole processes under a 4 GB address-space limit: asked for more than
    --max-nodes allows, a run is refused in one line within seconds, before it allocates
    (each of these reached gigabytes, or the machine's 24 GB, before)."""
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    src = tmp_path / "c64.csv"
    np.savetxt(src, np.c_[np.cos(t), np.sin(t)], delimiter=",")
    out = tmp_path / "m.vtk"
    r = sh(
        f"ulimit -v 4000000; deformesh all {src} -o {out} {' '.join(args)}",
        cwd=tmp_path,
        check=False,
    )
    err = r.stderr.decode()
    assert r.returncode == 1, err
    assert err.startswith(f"deformesh: error: {src}: ") and message in err
    assert err.count("\n") == 1 and not out.exists()
