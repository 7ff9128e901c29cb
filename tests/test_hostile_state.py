"""A catalogue of hostile state files: each one is what ``select`` or ``deform`` wrote,
then damaged one way (arrays of the wrong dtype, shape or values; metadata of the wrong
type, out of range or not finite; members that inflate far past what the grid needs).
``deform`` and ``triangulate`` answer each with one line on stderr naming the file,
exit 1, no traceback, nothing in the output folder, within a few seconds."""

import io
import json
import time
import zipfile

import numpy as np
import pytest

from .conftest import SAMPLES

pytestmark = pytest.mark.filterwarnings("error")  # (no numpy warning may leak either)


def _read(data: bytes) -> tuple[dict, dict]:
    zf = zipfile.ZipFile(io.BytesIO(data))
    meta = json.loads(zf.read("meta.json"))
    arrays = {
        n[:-4]: np.lib.format.read_array(io.BytesIO(zf.read(n)))
        for n in zf.namelist()
        if n.endswith(".npy")
    }
    return meta, arrays


def _write(meta, arrays: dict, raw: dict | None = None) -> bytes:
    """A state archive from its parts; ``raw`` members are stored as given (deflated)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as zf:
        text = meta if isinstance(meta, str) else json.dumps(meta)
        zf.writestr("meta.json", text, zipfile.ZIP_DEFLATED)
        for name, a in arrays.items():
            b = io.BytesIO()
            np.lib.format.write_array(b, a, allow_pickle=True)
            zf.writestr(f"{name}.npy", b.getvalue())
        for name, b in (raw or {}).items():
            zf.writestr(name, b, zipfile.ZIP_DEFLATED)
    return buf.getvalue()


def _set(path: str, value):
    """A mutation setting ``meta[a][b]...`` (dotted path) to ``value``."""

    def mutate(meta, arrays):
        *head, last = path.split(".")
        d = meta
        for k in head:
            d = d[k]
        d[last] = value

    return mutate


def _arr(name: str, fn):
    """A mutation replacing array ``name`` by ``fn(array)``."""

    def mutate(meta, arrays):
        arrays[name] = fn(arrays[name].copy())

    return mutate


def _put(name: str, index, value, dtype=None):
    def fn(a):
        if dtype is not None:
            a = a.astype(dtype)
        a[index] = value
        return a

    return _arr(name, fn)


def _swap_nx_ny(meta, arrays):
    g = meta["grid"]
    assert g["nx"] != g["ny"]
    g["nx"], g["ny"] = g["ny"], g["nx"]


def _bomb(name: str):
    """A member that inflates to 200 MB: a valid .npy header claiming the data."""

    def mutate(meta, arrays):
        a = arrays.pop(name)
        n = 200_000_000 // (a.itemsize * (a.shape[1] if a.ndim == 2 else 1))
        head = io.BytesIO()
        shape = (n,) + a.shape[1:]
        np.lib.format.write_array_header_1_0(
            head, {"descr": a.dtype.str, "fortran_order": False, "shape": shape}
        )
        return {f"{name}.npy": head.getvalue() + bytes(n * a.dtype.itemsize * (a.size // len(a)))}

    return mutate


def _member_method(name: str, method: int, flags: int = 0, corrupt: bool = False):
    """A mutation storing member ``name`` with zip ``method`` (a number zipfile may not
    know: patched into both headers), ``flags`` set, or its compressed data corrupted."""

    def after(data: bytes) -> bytes:
        zf = zipfile.ZipFile(io.BytesIO(data))
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w") as out:
            for info in zf.infolist():
                body = zf.read(info)
                known = method in (zipfile.ZIP_DEFLATED, zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA)
                kind = method if info.filename == name and known else zipfile.ZIP_STORED
                out.writestr(zipfile.ZipInfo(info.filename, info.date_time), body, kind)
        b = bytearray(buf.getvalue())
        info = zipfile.ZipFile(io.BytesIO(bytes(b))).getinfo(name)
        local = info.header_offset
        central = bytes(b).index(b"PK\x01\x02")
        while bytes(b[central + 46 : central + 46 + len(name)]) != name.encode():
            central = bytes(b).index(b"PK\x01\x02", central + 1)
        if method not in (zipfile.ZIP_DEFLATED, zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA, 0):
            b[local + 8 : local + 10] = method.to_bytes(2, "little")
            b[central + 10 : central + 12] = method.to_bytes(2, "little")
        b[local + 6] |= flags
        b[central + 8] |= flags
        if corrupt:
            start = local + 30 + len(name) + int.from_bytes(b[local + 28 : local + 30], "little")
            for k in range(start + 8, start + info.compress_size - 4, 3):
                b[k] ^= 0x5A
        return bytes(b)

    return lambda meta, arrays: {"zip": after}


def _shuffle_points(collapse: bool = False):
    """A deformed state's grid nodes off the path shuffled (or all moved to one place)."""

    def mutate(meta, arrays):
        p = arrays["points"].copy()
        off = np.ones(len(p), dtype=bool)
        off[arrays["path_nodes"]] = False
        k = np.flatnonzero(off)
        p[k] = p[k].mean(axis=0) if collapse else p[np.random.default_rng(2).permutation(k)]
        arrays["points"] = p

    return mutate


def _field(rows):
    def mutate(meta, arrays):
        arrays["size_field"] = rows

    return mutate


_ROWS = np.array([[x, y, 1.0 + x * x] for x in (-100.0, 0.0, 100.0) for y in (-100.0, 100.0)])


def _zeros_bomb(meta, arrays):
    """A 16,000 x 16,000 uniform grid whose diagonals.npy holds its 256 million cells as
    zeros deflated to a quarter of a MB, in a state whose own --max-nodes allows 10**12
    nodes: every size agrees, so only a bound of the tool's own stops the reading."""
    meta["options"]["max_nodes"] = 10**12
    meta["grid"]["nx"] = meta["grid"]["ny"] = 16_000
    n = 16_000 * 16_000
    arrays.pop("diagonals")
    head = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        head, {"descr": "|u1", "fortran_order": False, "shape": (n,)}
    )
    return {"stream": ("diagonals.npy", head.getvalue(), n)}


def _with_stream(data: bytes, member: str, head: bytes, size: int) -> bytes:
    """The archive with ``member`` added: ``head`` then ``size`` zero bytes, deflated as
    they are written (never all in memory)."""
    buf = io.BytesIO(data)
    with zipfile.ZipFile(buf, "a") as zf:
        info = zipfile.ZipInfo(member)
        info.compress_type = zipfile.ZIP_DEFLATED
        with zf.open(info, "w", force_zip64=True) as w:
            w.write(head)
            chunk = bytes(2**24)
            for start in range(0, size, len(chunk)):
                w.write(chunk[: min(len(chunk), size - start)])
    return buf.getvalue()


def _duplicate_leaf(meta, arrays):
    """One leaf replaced by a copy of another of the same level: the leaves still add
    up to the box's area, but one cell is covered twice and another not at all."""
    lv = arrays["leaf_level"]
    same = np.flatnonzero(lv == lv[0])
    k = same[1]
    for name in ("leaf_i", "leaf_j"):
        arrays[name] = arrays[name].copy()
        arrays[name][k] = arrays[name][same[0]]


# (stage, grid, mutation); stage "selected" goes to deform, "deformed" to triangulate
CASES = {
    # arrays of the wrong dtype, shape or kind
    "diagonals-2": ("selected", "graded", _put("diagonals", 0, 2)),
    "diagonals-255": ("selected", "uniform", _put("diagonals", 3, 255)),
    "diagonals-negative": ("selected", "uniform", _put("diagonals", 0, -1, np.int64)),
    "diagonals-float": ("selected", "graded", _arr("diagonals", lambda a: a.astype(float))),
    "diagonals-2d": ("selected", "uniform", _arr("diagonals", lambda a: a[:, None])),
    "diagonals-object": ("selected", "uniform", _arr("diagonals", lambda a: a.astype(object))),
    "diagonals-bool": ("selected", "graded", _arr("diagonals", lambda a: a.astype(bool))),
    "diagonals-0d": ("selected", "uniform", _arr("diagonals", lambda a: np.array(1))),
    "points-complex": ("deformed", "graded", _arr("points", lambda a: a.astype(complex))),
    "points-3-columns": ("deformed", "uniform", _arr("points", lambda a: np.c_[a, a[:, 0]])),
    "contour-structured": (
        "selected",
        "graded",
        _arr("contour_points", lambda a: a.view([("x", "f8"), ("y", "f8")]).ravel()),
    ),
    # path nodes repeated, shuffled or out of range
    "path-repeated": ("selected", "graded", _arr("path_nodes", lambda a: np.r_[a[:1], a[:-1]])),
    "path-shuffled": ("selected", "uniform", _arr("path_nodes", lambda a: a[::-1].copy())),
    "path-node-negative": ("selected", "graded", _put("path_nodes", 5, -3)),
    "path-node-huge": ("selected", "uniform", _put("path_nodes", 5, 2**62)),
    "path-source-repeated": ("selected", "graded", _put("path_source", 2, 1)),
    "path-source-shuffled": (
        "deformed",
        "graded",
        _arr("path_source", np.random.default_rng(1).permutation),
    ),
    "ring-negative": ("selected", "graded", _put("path_ring", 0, -1)),
    "ring-huge": ("deformed", "uniform", _put("path_ring", 4, 2**40)),
    "ring-starts-huge": ("selected", "graded", _put("contour_starts", 1, 2**62)),
    # values that are not finite or far out
    "target-nan": ("selected", "graded", _put("path_targets", 3, np.nan)),
    "target-inf": ("selected", "uniform", _put("path_targets", 3, np.inf)),
    "target-1e300": ("selected", "graded", _put("path_targets", 3, 1e300)),
    "contour-nan": ("deformed", "graded", _put("contour_points", 7, np.nan)),
    "contour-1e300": ("selected", "uniform", _put("contour_points", 7, 1e300)),
    "points-nan": ("deformed", "graded", _put("points", 9, np.nan)),
    "points-1e300": ("deformed", "uniform", _put("points", 9, 1e300)),
    "leaf-level-huge": ("selected", "graded", _put("leaf_level", 0, 2**40)),
    "leaf-i-negative": ("deformed", "graded", _put("leaf_i", 0, -1)),
    # grid metadata
    "grid-x0-inf": ("selected", "uniform", _set("grid.x0", float("inf"))),
    "grid-x0-nan": ("selected", "graded", _set("grid.x0", float("nan"))),
    "grid-x0-huge": ("selected", "graded", _set("grid.x0", 1e300)),
    "grid-hx-tiny": ("selected", "uniform", _set("grid.hx", 1e-300)),
    "grid-hx-negative": ("deformed", "graded", _set("grid.hx", -0.1)),
    "grid-hx-string": ("selected", "graded", _set("grid.hx", "0.1")),
    "grid-nx-ny-swapped": ("selected", "uniform", _swap_nx_ny),
    "grid-nx-ny-swapped-graded": ("deformed", "graded", _swap_nx_ny),
    "grid-nx-float": ("selected", "uniform", _set("grid.nx", 12.5)),
    "grid-nx-huge": ("selected", "uniform", _set("grid.nx", 10**12)),
    "grid-top-huge": ("selected", "graded", _set("grid.top", 10**6)),
    "grid-a-list": ("selected", "graded", _set("grid", [1, 2])),
    # metadata fields of the wrong JSON type
    "h-string": ("selected", "graded", _set("h", "0.1")),
    "h-nan": ("deformed", "uniform", _set("h", float("nan"))),
    "notes-int": ("selected", "uniform", _set("notes", 3)),
    "notes-of-dicts": ("deformed", "graded", _set("notes", [{"a": 1}])),
    "refinements-list": ("selected", "uniform", _set("refinements", [1])),
    "searched-further-negative": ("selected", "uniform", _set("searched_further", -5)),
    "exterior-string": ("selected", "graded", _set("exterior", "no")),
    "source-dict": ("deformed", "graded", _set("source", {"a": 1})),
    "ring-labels-int": ("selected", "graded", _set("ring_labels", 7)),
    "meta-a-list": ("selected", "graded", lambda m, a: {"meta": "[1, 2]"}),
    "meta-10000-deep": ("selected", "uniform", lambda m, a: {"meta": "[" * 10_000 + "]" * 10_000}),
    # recorded options of the wrong type or out of range
    "option-steps-string": ("selected", "graded", _set("options.steps", "many")),
    "option-steps-zero": ("selected", "graded", _set("options.steps", 0)),
    "option-unknown": ("deformed", "graded", _set("options.colour", "red")),
    "option-size-field-device": ("selected", "graded", _set("options.size_field", "/dev/zero")),
    "option-max-nodes-float": ("selected", "uniform", _set("options.max_nodes", 1.5)),
    "option-growth-negative": ("selected", "graded", _set("options.growth", -2.0)),
    "option-solver-unknown": ("selected", "graded", _set("options.solver", "magic")),
    "option-box-3": ("deformed", "uniform", _set("options.box", [0, 0, 1])),
    "option-size-list": ("selected", "graded", _set("options.size", ["d"])),
    "option-size-slow": (
        "selected",
        "graded",
        _set("options.size", "+".join(["sin(x)"] * 300)),
    ),
    "options-deep": (
        "selected",
        "graded",
        _set("options.improve", json.loads("[" * 500 + "]" * 500)),
    ),
    # members that inflate far past what the grid needs
    "bomb-diagonals": ("selected", "graded", _bomb("diagonals")),
    "bomb-meta": ("selected", "uniform", lambda m, a: {"meta": " " * 100_000_000 + "{}"}),
    "bomb-points": ("deformed", "graded", _bomb("points")),
    "bomb-own-max-nodes": ("selected", "uniform", _zeros_bomb),
    # recorded options that are not set, fields a grid does not have, numbers too long
    "option-max-nodes-null": ("selected", "uniform", _set("options.max_nodes", None)),
    "option-growth-null": ("selected", "graded", _set("options.growth", None)),
    "uniform-top-string": ("selected", "uniform", _set("grid.top", "3")),
    "uniform-top-null": ("selected", "uniform", _set("grid.top", None)),
    "uniform-top-list": ("selected", "uniform", _set("grid.top", [1])),
    "uniform-top-1e308": ("selected", "uniform", _set("grid.top", 1e308)),
    "uniform-top-1e9": ("deformed", "uniform", _set("grid.top", 10**9)),
    "graded-top-61": ("selected", "graded", _set("grid.top", 61)),
    "grid-hx-400-digits": ("selected", "uniform", _set("grid.hx", 10**400)),
    "h-400-digits": ("deformed", "graded", _set("h", 10**400)),
    "meta-unknown-field": ("selected", "graded", _set("colour", "red")),
    # members encrypted, compressed with methods deformesh does not read, or corrupt
    "member-encrypted": ("selected", "graded", _member_method("diagonals.npy", 0, flags=1)),
    "member-method-99": ("selected", "uniform", _member_method("path_nodes.npy", 99)),
    "member-method-shrink": ("deformed", "graded", _member_method("points.npy", 1)),
    "member-deflate-corrupt": (
        "selected",
        "uniform",
        _member_method("path_targets.npy", zipfile.ZIP_DEFLATED, corrupt=True),
    ),
    "member-bzip2-corrupt": (
        "deformed",
        "graded",
        _member_method("points.npy", zipfile.ZIP_BZIP2, corrupt=True),
    ),
    "member-lzma-corrupt": (
        "selected",
        "graded",
        _member_method("contour_points.npy", zipfile.ZIP_LZMA, corrupt=True),
    ),
    "meta-deflate-corrupt": (
        "selected",
        "uniform",
        _member_method("meta.json", zipfile.ZIP_DEFLATED, corrupt=True),
    ),
    # deformed points that fold the grid
    "graded-points-shuffled": ("deformed", "graded", _shuffle_points()),
    "graded-points-collapsed": ("deformed", "graded", _shuffle_points(collapse=True)),
    "uniform-points-shuffled": ("deformed", "uniform", _shuffle_points()),
    "uniform-points-collapsed": ("deformed", "uniform", _shuffle_points(collapse=True)),
    # a size function that is a path, not numbers, or not positive
    "size-field-path": ("selected", "graded", _set("options.size_field", "/etc/passwd")),
    "size-field-string": ("deformed", "uniform", _set("options.size_field", "f.csv")),
    "size-field-structured": (
        "selected",
        "graded",
        _field(_ROWS.copy().view([("x", "f8"), ("y", "f8"), ("f", "f8")]).ravel()),
    ),
    "size-field-complex": ("selected", "uniform", _field(_ROWS.astype(complex))),
    "size-field-negative": ("selected", "graded", _field(_ROWS * [1, 1, -1])),
    "size-field-not-a-grid": ("deformed", "graded", _field(_ROWS[:-1])),
    "size-and-size-field": (
        "selected",
        "graded",
        lambda m, a: [_set("options.size", "1 + d")(m, a), _field(_ROWS)(m, a)][0],
    ),
    "size-negative": ("selected", "uniform", _set("options.size", "-1")),
    "size-zero-somewhere": ("selected", "graded", _set("options.size", "x - x")),
    "size-negative-deformed": ("deformed", "graded", _set("options.size", "0 - 2")),
    # a graded grid's leaves that do not tile its box
    "leaf-duplicated": ("selected", "graded", _duplicate_leaf),
}


@pytest.fixture(scope="module")
def states(tmp_path_factory):
    """What select (and deform) write for a drawing with a hole, on both grids (extra
    boundary nodes on the uniform one, nodes sliding along the contour on the graded)."""
    from click.testing import CliRunner

    from deformesh_cli.cli import cli

    d = tmp_path_factory.mktemp("states")
    out = {}
    for grid in ("graded", "uniform"):
        sel, dfm = d / f"{grid}.sel", d / f"{grid}.def"
        src = SAMPLES / "bracket.svg"
        for args in (["select", src, "--grid", grid, "-o", sel], ["deform", sel, "-o", dfm]):
            r = CliRunner().invoke(cli, [str(a) for a in args] + ["-q"])
            assert r.exit_code == 0, r.output
        out["selected", grid] = sel.read_bytes()
        out["deformed", grid] = dfm.read_bytes()
    return out


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_hostile_state_is_one_line_and_leaves_nothing(run, states, tmp_path, name):
    stage, grid, mutate = CASES[name]
    meta, arrays = _read(states[stage, grid])
    change = mutate(meta, arrays) or {}
    f = tmp_path / f"{name}.state"
    raw = {k: v for k, v in change.items() if k.endswith(".npy")}
    data = _write(change.get("meta", meta), arrays, raw)
    if "zip" in change:
        data = change["zip"](data)
    if "stream" in change:
        data = _with_stream(data, *change["stream"])
    f.write_bytes(data)
    out = tmp_path / "out"
    out.mkdir()
    t = time.perf_counter()
    if stage == "selected":
        r = run("deform", f, "-o", out / "d.state")
    else:
        r = run("triangulate", f, "-o", out / "m.msh", "--png", out / "m.png")
    assert time.perf_counter() - t < 20  # (a bound, not a benchmark: no hang)
    assert r.exit_code == 1, r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.startswith(f"deformesh: error: {f}:"), r.stderr
    assert list(out.iterdir()) == []


def test_the_states_it_writes_pass_its_checks(run, states, tmp_path):
    """The catalogue's undamaged states go through (so its refusals are the damage's)."""
    for (stage, grid), data in states.items():
        meta, arrays = _read(data)
        f = tmp_path / f"{stage}-{grid}.state"
        f.write_bytes(_write(meta, arrays))
        if stage == "selected":
            r = run("deform", f, "-o", tmp_path / "d.state", "-q")
        else:
            r = run("triangulate", f, "-o", tmp_path / "m.msh", "-q")
        assert r.exit_code == 0, r.stderr


@pytest.mark.parametrize(
    "leaves",
    [
        # one root of two levels: four level-0 cells, one of them twice (one missing)
        [(0, 0, 0), (0, 1, 0), (0, 0, 1), (0, 0, 1)],
        # three level-1 cells and the four level-0 cells inside the first of them
        [(1, 0, 0), (1, 1, 0), (1, 0, 1), (0, 0, 0), (0, 1, 0), (0, 0, 1), (0, 1, 1)],
    ],
    ids=["a-leaf-twice", "nested-leaves"],
)
def test_leaves_that_cover_the_area_but_do_not_tile_are_refused(leaves):
    """Leaves whose areas add up to the box's, but that overlap: not a quadtree."""
    from deformesh_cli import state
    from deformesh_cli.errors import InputError

    top = 1 if len(leaves) == 4 else 2
    lv, i, j = (np.array(c, dtype=np.int64) for c in zip(*leaves, strict=True))
    grid = {"x0": 0.0, "y0": 0.0, "hx": 1.0, "hy": 1.0, "nx": 1, "ny": 1, "top": top}
    with pytest.raises(InputError, match="do not tile its box"):
        state._graded_grid(grid, {"leaf_level": lv, "leaf_i": i, "leaf_j": j})
