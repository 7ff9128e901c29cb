"""The intermediate file between ``select``, ``deform`` and ``triangulate``.

A state file is an uncompressed ZIP archive (so it streams through pipes and
can be inspected with ``unzip -l``) holding ``meta.json`` and ``.npy`` arrays.
The layout is documented in the README ("The state file"); :data:`VERSION`
changes whenever it does.  Archives are written with fixed timestamps, so the
same input gives the same bytes.
"""

from __future__ import annotations

import io
import json
import lzma
import math
import zipfile
import zlib
from dataclasses import dataclass, field

import numpy as np

from . import __version__
from .contour import MAX_COORDINATE, Contour, make_contour
from .errors import InputError, LimitError, OptionError, WriteError, printable
from .expression import Expression
from .files import parse_json
from .geometry import signed_areas
from .options import MeshOptions, from_record
from .options import fields as option_fields
from .pipeline import Laid, lay
from .select import DEFAULT_MAX_NODES, Grid, Selection
from .select.construct import GradedGrid, GradedSelection
from .select.graded import MAX_CELLS_ACROSS, Quadtree
from .size import MAX_FIELD_ROWS, from_rows

FORMAT = "deformesh-state"
VERSION = 6
STAGES = ("selected", "deformed")

_ARRAYS = {
    # name: (dtype kind, ndim, trailing shape)
    "contour_points": ("f", 2, (2,)),
    "contour_lines": ("i", 1, ()),
    "path_nodes": ("i", 1, ()),
    "path_targets": ("f", 2, (2,)),
    "path_source": ("i", 1, ()),
    "path_ring": ("i", 1, ()),
    "contour_starts": ("i", 1, ()),
    "diagonals": ("u", 1, ()),
}
_EPOCH = (1980, 1, 1, 0, 0, 0)


@dataclass
class State:
    stage: str
    contour: Contour
    selection: Selection
    points: np.ndarray | None = None  # deformed coordinates, stage "deformed"
    #: the :class:`~.options.MeshOptions` fields of the stages run so far (their values;
    #: never ``size_field``, a path: the field's rows are :attr:`size_field`)
    options: dict = field(default_factory=dict)
    #: the rows ``x, y, f`` of the size field given to ``select`` or ``deform``, or None
    size_field: np.ndarray | None = None
    #: the contour the grid is laid for (:func:`.pipeline.lay`: with ``--max-h`` its
    #: long edges split, on the graded grid its sharp ears cut): derived from the
    #: contour and the recorded options
    laid: Laid | None = None
    #: the boundary layers the options ask for (:func:`.pipeline.grow_layers`), the grid
    #: laid for their top; derived from the contour and the options, or None
    stacks: object = None

    def __post_init__(self):
        if self.laid is None:
            graded = isinstance(self.selection, GradedSelection)
            self.laid, self.stacks = laid_for(self.contour, self.options, graded)

    @property
    def grid_contour(self) -> Contour:
        return self.laid.grid

    def size_function(self, name: str):
        """The size function the state records (a size field's rows, or an expression),
        or None; its errors name the state file ``name``."""
        from .size import from_expression

        if self.size_field is not None:
            return from_rows(self.size_field, f"{name}: its size field")
        if self.options.get("size") is not None:
            return from_expression(self.options["size"], self.laid.contour)
        return None


def _stacks(contour: Contour, options: dict):
    """The boundary layers the recorded ``options`` ask for, or None."""
    from .pipeline import grow_layers

    o = from_record(MeshOptions, options)
    return grow_layers(contour, o) if o.layers else None


def laid_for(
    contour: Contour, options: dict, graded: bool, max_nodes: int | None = None, stacks=None
):
    """``(laid, stacks)``: the contour the grid is laid for under the recorded
    ``options`` (with layers, their top: :func:`.pipeline.grow_layers`, or ``stacks``
    if already grown), and the layers, or None; ``max_nodes`` bounds the laying (not
    the layers)."""
    from .pipeline import core_options

    o = from_record(MeshOptions, options)
    if stacks is None:
        stacks = _stacks(contour, options)
    if max_nodes is not None:  # (the grid's contour bounded: by the path, when loading)
        o = o.replace(max_nodes=max_nodes)
    if stacks is None:
        return lay(contour, o, graded), None
    return lay(stacks.top, core_options(o), graded), stacks


def dumps(state: State) -> bytes:
    """Serialise a state to bytes (deterministic)."""
    sel, g = state.selection, state.selection.grid
    graded = not isinstance(g, Grid)
    if not graded:
        grid_meta = {"x0": g.x0, "y0": g.y0, "hx": g.hx, "hy": g.hy, "nx": g.nx, "ny": g.ny}
    else:
        t = g.tree
        grid_meta = {"kind": "graded", "x0": t.x0, "y0": t.y0, "hx": t.hx, "hy": t.hy,
                     "nx": t.nx, "ny": t.ny, "top": t.top}  # fmt: skip
    meta = {
        "format": FORMAT,
        "version": VERSION,
        "stage": state.stage,
        "written_by": f"deformesh {__version__}",
        "source": state.contour.source,
        "grid": grid_meta,
        "h": sel.h,
        "h_rule": sel.h_rule,
        "searched_further": sel.searched_further,
        "refinements": sel.refinements,
        "path_rule": sel.path_rule,
        "exterior": bool(sel.exterior),
        "notes": list(sel.notes),
        "ring_labels": list(state.contour.ring_labels),
        "options": {k: list(v) if isinstance(v, tuple) else v for k, v in state.options.items()},
    }
    arrays = {
        "contour_points": state.contour.points,
        "contour_lines": state.contour.lines,
        "path_nodes": sel.path_nodes,
        "path_targets": sel.path_targets,
        "path_source": sel.path_source,
        "path_ring": sel.path_ring,
        "contour_starts": np.asarray(state.contour.starts, dtype=np.int64),
        "diagonals": sel.diagonals,
    }
    if graded:
        arrays.update(leaf_level=g.tree.level, leaf_i=g.tree.i, leaf_j=g.tree.j)
        arrays["kept"] = sel.kept_triangles().astype(np.uint8)
    if state.stage == "deformed":
        arrays["points"] = state.points
    if state.size_field is not None:
        arrays["size_field"] = np.asarray(state.size_field, dtype=np.float64)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as zf:
        zf.writestr(
            zipfile.ZipInfo("meta.json", _EPOCH), json.dumps(meta, indent=1, sort_keys=True)
        )
        for name, arr in arrays.items():
            b = io.BytesIO()
            np.lib.format.write_array(b, _plain(arr))
            zf.writestr(zipfile.ZipInfo(f"{name}.npy", _EPOCH), b.getvalue())
    return buf.getvalue()


def _plain(arr: np.ndarray) -> np.ndarray:
    """An array as stored: contiguous numbers only (never Python objects)."""
    a = np.ascontiguousarray(arr)
    if a.dtype.kind not in "biuf":
        raise WriteError(f"a state file stores numbers only, not {a.dtype}")
    return a


def loads(data: bytes, name: str = "<state>", want: str | None = None) -> State:
    """Parse and check a state file; ``want`` is the stage the caller needs.

    Everything is checked before any work, and every problem is an :class:`InputError`
    naming ``name``: the metadata against its schema (types, ranges, finite numbers,
    a grid that fits the recorded ``--max-nodes``), each array's dtype and shape from
    its ``.npy`` header before its data is read (so no member is read past what the
    grid needs), then the values and their consistency: the path steps along grid
    edges, visits each node once and carries each contour point once, in ring order,
    onto that point; every coordinate lies in the grid's box.  Arrays are read as
    plain numbers, never as Python objects.
    """
    if not data:
        raise InputError(f"{name}: empty input, expected a deformesh state file")
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
        meta = parse_json(_member(zf, "meta.json", MAX_META_BYTES, name))
    except (zipfile.BadZipFile, KeyError, ValueError, EOFError, RecursionError, *_CORRUPT):
        hint = " (truncated?)" if data[:2] == b"PK" else ""
        raise InputError(f"{name}: not a deformesh state file{hint}") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise InputError(f"{name}: not a deformesh state file (no '{FORMAT}' header)")
    if meta.get("version") != VERSION or isinstance(meta.get("version"), bool):
        raise InputError(
            f"{name}: state file version {meta.get('version')!r} (written by "
            f"{meta.get('written_by', 'unknown')!r}); this deformesh {__version__} reads "
            f"version {VERSION}: re-run 'deformesh select'"
        )
    stage = meta.get("stage")
    if not isinstance(stage, str) or stage not in STAGES:
        raise InputError(f"{name}: unknown stage {stage!r} in state file")
    if want is not None and stage != want:
        advice = {"selected": "deformesh select", "deformed": "deformesh deform"}[want]
        raise InputError(f"{name}: state is at stage '{stage}', expected '{want}' (from {advice})")
    try:
        return _parse(zf, meta, stage)
    except _Damaged as exc:
        raise InputError(f"{name}: damaged state file ({exc})") from None
    except InputError as exc:  # the contour's own checks name the contour's source
        raise InputError(f"{name}: damaged state file (its contour: {exc})") from None
    except (zipfile.BadZipFile, EOFError, OSError, ValueError, *_CORRUPT) as exc:
        raise InputError(f"{name}: damaged state file ({exc.__class__.__name__}: {exc})") from None


#: What a member's corrupt compressed data raises (bzip2's is an OSError).
_CORRUPT = (zlib.error, lzma.LZMAError)


#: The largest ``meta.json`` read: it holds a few numbers, short notes and ring labels.
MAX_META_BYTES = 16 * 2**20
#: The largest ``.npy`` header read (numpy's own limit on untrusted headers).
_MAX_HEADER = 10_000


class _Damaged(InputError):
    """What is wrong with a state file (the message ``loads`` puts in parentheses)."""


#: How a member may be stored: as deformesh writes it, or compressed by a zip tool
#: with a method Python reads; never encrypted.
_METHODS = (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED, zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA)


def _info(zf: zipfile.ZipFile, member: str) -> zipfile.ZipInfo:
    """A member's entry, refused if encrypted or stored with a method deformesh does not
    read (before any of its data is)."""
    info = zf.getinfo(member)
    if info.flag_bits & 0x1:
        raise _Damaged(f"{member} is encrypted")
    if info.compress_type not in _METHODS:
        raise _Damaged(f"{member} is compressed with zip method {info.compress_type}")
    if info.compress_type != zipfile.ZIP_STORED and info.file_size > max(
        MIN_BOMB_BYTES, MAX_INFLATION * info.compress_size
    ):
        raise _Damaged(
            f"{member} inflates {info.file_size / max(info.compress_size, 1):.0f} times: "
            f"a state's numbers compress less than {MAX_INFLATION} times"
        )
    return info


#: A compressed member may inflate at most this many times (past :data:`MIN_BOMB_BYTES`):
#: the floats and node numbers of a state compress far less; a run of zeros (a zip bomb:
#: gigabytes from a few megabytes) far more.  A bound of the tool, whatever the state's
#: own ``--max-nodes`` says.
MAX_INFLATION = 100
MIN_BOMB_BYTES = 2**20


def _member(zf: zipfile.ZipFile, member: str, limit: int, name: str) -> bytes:
    """A member's bytes, refused (without reading further) past ``limit``."""
    try:
        info = _info(zf, member)
    except _Damaged as exc:
        raise InputError(f"{name}: damaged state file ({exc})") from None
    if info.file_size > limit:
        raise InputError(f"{name}: damaged state file ({member} is larger than it can be)")
    with zf.open(info) as fh:
        b = fh.read(limit + 1)
    if len(b) > limit:
        raise InputError(f"{name}: damaged state file ({member} is larger than it can be)")
    return b


def _is_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _is_count(v, low: int = 0) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= low


def _is_coordinate(v) -> bool:
    return _is_number(v) and abs(v) <= MAX_COORDINATE


def _is_positive(v) -> bool:
    return _is_number(v) and v > 0


def _is_text_list(v) -> bool:
    return isinstance(v, list) and all(isinstance(x, str) for x in v)


#: meta.json: key -> (check, what it must be)
_META = {
    "source": (lambda v: isinstance(v, str), "a string"),
    "written_by": (lambda v: isinstance(v, str), "a string"),
    "grid": (lambda v: isinstance(v, dict), "a mapping"),
    "h": (_is_positive, "a finite number > 0"),
    "h_rule": (lambda v: isinstance(v, str), "a string"),
    "searched_further": (_is_count, "a whole number >= 0"),
    "refinements": (_is_count, "a whole number >= 0"),
    "path_rule": (lambda v: isinstance(v, str), "a string"),
    "exterior": (lambda v: isinstance(v, bool), "true or false"),
    "notes": (_is_text_list, "a list of strings"),
    "ring_labels": (_is_text_list, "a list of strings"),
    "options": (lambda v: isinstance(v, dict), "a mapping"),
}
_GRID = {
    "x0": (_is_coordinate, f"a finite number of size at most {MAX_COORDINATE:g}"),
    "y0": (_is_coordinate, f"a finite number of size at most {MAX_COORDINATE:g}"),
    "hx": (_is_positive, "a finite number > 0"),
    "hy": (_is_positive, "a finite number > 0"),
    "nx": (lambda v: _is_count(v, 1), "a whole number >= 1"),
    "ny": (lambda v: _is_count(v, 1), "a whole number >= 1"),
}
#: The deepest graded grid a state file may describe (cells 2**60 times the finest).
MAX_LEVELS = int(math.log2(MAX_CELLS_ACROSS))
_GRADED = {
    "kind": (lambda v: v == "graded", "'graded'"),
    "top": (lambda v: _is_count(v) and v <= MAX_LEVELS, f"a whole number from 0 to {MAX_LEVELS}"),
}


def _check_schema(meta: dict) -> None:
    for table, where, d in ((_META, "", meta), (_GRID, "grid.", meta.get("grid"))):
        if table is _GRID and "kind" in d:
            table = {**_GRID, **_GRADED}
        for key, (ok, what) in table.items():
            if key not in d:
                raise _Damaged(f"{where}{key} is missing")
            if not ok(d[key]):
                raise _Damaged(f"{where}{key} is {_short(d[key])}, it must be {what}")
        extra = sorted(set(d) - set(table) - (_HEADER if table is _META else set()))
        if extra:
            raise _Damaged(f"{printable(where + extra[0])} is not a field of this state file")


#: The fields ``loads`` reads before the schema.
_HEADER = {"format", "version", "stage"}


def _short(v) -> str:
    text = json.dumps(v) if not isinstance(v, float) else repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


def _parse(zf: zipfile.ZipFile, meta: dict, stage: str) -> State:
    _check_schema(meta)
    options = _options(meta)
    g = meta["grid"]
    graded = "kind" in g
    max_nodes = options.get("max_nodes", DEFAULT_MAX_NODES)
    # the grid's size, bounded before any array is read
    cells = g["nx"] * g["ny"]
    nodes = (g["nx"] + 1) * (g["ny"] + 1)
    if nodes > max_nodes:
        raise _Damaged(f"a {g['nx']} x {g['ny']} grid is over its --max-nodes {max_nodes}")
    if graded and max(g["nx"], g["ny"]) * 2 ** g["top"] > MAX_CELLS_ACROSS:
        raise _Damaged(f"the graded grid is over {MAX_CELLS_ACROSS} finest cells across")
    x1, y1 = (g["x0"] + g["nx"] * g["hx"] * 2 ** g.get("top", 0),
              g["y0"] + g["ny"] * g["hy"] * 2 ** g.get("top", 0))  # fmt: skip
    if not (_is_coordinate(x1) and _is_coordinate(y1)):
        raise _Damaged("the grid's box is beyond double precision")
    span = max(abs(g["x0"]), abs(x1), abs(g["y0"]), abs(y1))
    if min(g["hx"], g["hy"]) < 16 * np.finfo(float).eps * span:
        raise _Damaged("the grid step is below the coordinates' resolution")
    spec = dict(_ARRAYS)
    if stage == "deformed":
        spec["points"] = ("f", 2, (2,))
    if "size_field.npy" in zf.namelist():  # optional: a size field's rows x, y, f
        spec["size_field"] = ("f", 2, (3,))
    if graded:  # the graded grid's leaves, and which of its triangles the domain keeps
        spec.update(leaf_level=("i", 1, ()), leaf_i=("i", 1, ()), leaf_j=("i", 1, ()))
        spec["kept"] = ("u", 1, ())
    heads = {key: _header(zf, key, *spec[key]) for key in spec}
    rows = {key: shape[0] for key, (shape, _) in heads.items()}
    if graded:
        leaves = rows["leaf_level"]
        if not rows["leaf_i"] == rows["leaf_j"] == leaves or not 1 <= leaves <= max_nodes:
            raise _Damaged("the graded grid's leaf arrays do not match")
        cells, nodes = leaves, max_nodes  # (the node count is known once the leaves are)
    p = rows["path_nodes"]
    same = {"diagonals": cells, **dict.fromkeys(("path_targets", "path_source", "path_ring"), p)}
    if not graded and stage == "deformed":
        same["points"] = nodes
    same["contour_lines"] = rows["contour_points"]
    for key, n in same.items():
        if rows[key] != n:
            raise _Damaged(f"{key} has {rows[key]} rows, expected {n}")
    # (a path covers the points the grid was laid for, which the contour's cut ears
    # leave out: :func:`_check_path` matches it to them once they are known)
    if not (rows["contour_points"] >= 3 and 3 <= p <= nodes):
        raise _Damaged("the path and the contour do not match the grid's size")
    if not 2 <= rows["contour_starts"] <= rows["contour_points"] // 3 + 1:
        raise _Damaged("the ring starts do not match the contour")
    if graded and stage == "deformed" and rows["points"] > max_nodes:
        raise _Damaged("points has more rows than the grid can have nodes")
    if "size_field" in spec and not 4 <= rows["size_field"] <= MAX_FIELD_ROWS:
        raise _Damaged(f"size_field has {rows['size_field']} rows, not 4 to {MAX_FIELD_ROWS:,}")
    if "size_field" in spec and options.get("size") is not None:
        raise _Damaged("options.size and size_field.npy are both given")
    a = {key: _data(zf, key, *heads[key]) for key in spec}
    if graded:
        grid = _graded_grid(g, a)
        if stage == "deformed" and rows["points"] != grid.n_nodes:
            raise _Damaged(f"points has {rows['points']} rows, expected {grid.n_nodes}")
    else:
        grid = Grid(float(g["x0"]), float(g["y0"]), float(g["hx"]), float(g["hy"]),
                    g["nx"], g["ny"])  # fmt: skip
    labels = meta["ring_labels"] or None
    starts = a["contour_starts"]
    if (starts[0] != 0 or starts[-1] != len(a["contour_points"]) or (np.diff(starts) < 3).any()
            or labels is not None and len(labels) != len(starts) - 1):  # fmt: skip
        raise _Damaged("the ring starts or labels do not match the contour")
    contour = make_contour(
        a["contour_points"], a["contour_lines"], meta["source"],
        ring_starts=starts[:-1], ring_labels=labels,
    )  # fmt: skip
    if contour.n != len(a["contour_points"]):
        raise _Damaged("the contour repeats a ring's first point at its end")
    fields = {
        "grid": grid,
        "path_nodes": a["path_nodes"].astype(np.int64),
        "path_targets": a["path_targets"].astype(np.float64),
        "path_source": a["path_source"].astype(np.int64),
        "path_ring": a["path_ring"].astype(np.int64),
        "diagonals": a["diagonals"].astype(np.uint8),
        "h": float(meta["h"]),
        "h_rule": meta["h_rule"],
        "searched_further": meta["searched_further"],
        "refinements": meta["refinements"],
        "notes": list(meta["notes"]),
        "path_rule": meta["path_rule"],
        "exterior": meta["exterior"],
    }
    sel = (GradedSelection if graded else Selection)(**fields)
    stacks = _stacks(contour, options)  # (their refusals name the file: as any run's)
    try:  # (the grid was laid for the contour split at max_h: bounded by the path)
        laid, _ = laid_for(contour, options, graded, max(4, len(fields["path_nodes"])), stacks)
    except LimitError:
        raise _Damaged(
            "options.max_h splits the contour into more points than the path has"
        ) from None
    _check_path(laid.grid, sel, a)
    if graded:
        if len(a["kept"]) != len(sel.triangles()) or not np.isin(a["kept"], (0, 1)).all():
            raise _Damaged("kept: not one 0 or 1 per triangle of the grid")
        sel._kept = a["kept"].astype(bool)
    points = a.get("points")
    if points is not None and not graded:
        _check_unfolded(sel, points)
    field_rows = a.get("size_field")
    if field_rows is not None:
        try:
            from_rows(field_rows.astype(np.float64), "size_field.npy")
        except InputError as exc:
            raise _Damaged(str(exc)) from None
    return State(
        stage, contour, sel, None if points is None else points.astype(float), options,
        None if field_rows is None else field_rows.astype(np.float64), laid, stacks,
    )  # fmt: skip


def _check_unfolded(sel, points: np.ndarray) -> None:
    """A deformed uniform grid's triangles keep their orientation (the deformation
    folds none of them; moved or shuffled points do)."""
    area = signed_areas(points, sel.triangles())  # (points checked finite, in the box)
    if not (area > 0).all():
        raise _Damaged(f"points: {int((area <= 0).sum())} of the grid's triangles are folded")


def _header(zf: zipfile.ZipFile, key: str, kind: str, ndim: int, tail: tuple):
    """An array member's (shape, dtype), read from its .npy header alone."""
    try:
        info = _info(zf, f"{key}.npy")
    except KeyError:
        raise _Damaged(f"{key}.npy is missing") from None
    with zf.open(info) as fh:
        version = np.lib.format.read_magic(fh)
        read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                else np.lib.format.read_array_header_2_0)  # fmt: skip
        shape, fortran, dtype = read(fh, max_header_size=_MAX_HEADER)
        offset = fh.tell()
    ok_kind = dtype.kind == kind or (kind == "u" and dtype.kind == "i")
    if not ok_kind or dtype.fields is not None or dtype.hasobject or dtype.itemsize > 8:
        raise _Damaged(f"{key}: numbers of type {dtype}, expected {_KINDS[kind]}")
    if len(shape) != ndim or tuple(shape[1:]) != tail or fortran:
        raise _Damaged(f"{key}: shape {tuple(shape)}, expected {('n',) + tail}")
    if info.file_size != offset + math.prod(shape) * dtype.itemsize:
        raise _Damaged(f"{key}.npy does not hold the {tuple(shape)} array it announces")
    return shape, (dtype, offset)


_KINDS = {"f": "floats", "i": "integers", "u": "integers"}


def _data(zf: zipfile.ZipFile, key: str, shape: tuple, at: tuple) -> np.ndarray:
    dtype, offset = at
    with zf.open(f"{key}.npy") as fh:
        fh.read(offset)
        b = fh.read(math.prod(shape) * dtype.itemsize)
    a = np.frombuffer(b, dtype=dtype).reshape(shape)
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        raise _Damaged(f"{key}: a value that is not finite")
    return a.astype(a.dtype.newbyteorder("="))


def _check_path(contour: Contour, sel, a: dict) -> None:
    """The path's values: nodes, rings, sources and targets, and (deformed) the points."""
    grid = sel.grid
    nodes, src, ring = a["path_nodes"], a["path_source"], a["path_ring"]
    targets, n, m = a["path_targets"], grid.n_nodes, contour.n
    if nodes.min() < 0 or nodes.max() >= n or (np.diff(np.sort(nodes)) == 0).any():
        raise _Damaged("path_nodes: a node out of the grid, or visited twice")
    rings = len(contour.starts) - 1
    if ring.min() < 0 or ring.max() >= rings or (np.diff(ring) < 0).any():
        raise _Damaged("path_ring: not the contour's rings in order")
    if not (np.isin(np.arange(rings), ring)).all():
        raise _Damaged("path_ring: a ring without a path")
    if src.min() < -1 or src.max() >= m or np.count_nonzero(src >= 0) != m:
        raise _Damaged("path_source: not each contour point once")
    starts = np.asarray(contour.starts)
    for r in range(rings):
        s = src[(ring == r) & (src >= 0)]
        k = s - starts[r]
        size = starts[r + 1] - starts[r]
        step = np.arange(len(k))
        if len(k) != size or not (np.array_equal(k, step) or np.array_equal(k, -step % size)):
            raise _Damaged(f"path_source: ring {r}'s points are not in ring order")
    on = src >= 0
    if not np.array_equal(targets[on], contour.points[src[on]]):
        raise _Damaged("path_targets: a target is not its contour point")
    if a["diagonals"].max(initial=0) > 1 or a["diagonals"].min(initial=0) < 0:
        raise _Damaged("diagonals: a value other than 0 or 1")
    x0, y0, x1, y1 = grid.box
    pad = 1e-9 * max(x1 - x0, y1 - y0)
    for key in ("path_targets", "points"):
        q = a.get(key)
        if q is not None and not (
            (q[:, 0] >= x0 - pad).all() and (q[:, 0] <= x1 + pad).all()
            and (q[:, 1] >= y0 - pad).all() and (q[:, 1] <= y1 + pad).all()
        ):  # fmt: skip
            raise _Damaged(f"{key}: a point outside the grid's box")
    tri = sel.triangles()
    on_path = np.zeros(n, dtype=bool)
    on_path[nodes] = True
    tri = tri[on_path[tri].sum(axis=1) >= 2]  # (the only ones with a path step)
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    codes = edges[:, 0] * n + edges[:, 1]
    for r in range(rings):
        path = nodes[ring == r]
        step = np.sort(np.column_stack([path, np.roll(path, -1)]), axis=1)
        if not np.isin(step[:, 0] * n + step[:, 1], codes).all():
            raise _Damaged(f"path_nodes: ring {r}'s path leaves the grid's edges")


def _options(meta: dict) -> dict:
    """The state's recorded options, each checked against its field's kind; a size
    expression is data too: it is checked by the same parser as ``--size`` (never
    evaluated by Python)."""
    options = meta["options"]
    known = option_fields(MeshOptions)
    for key, value in options.items():
        f = known.get(key)
        if f is None:
            raise _Damaged(f"options.{key} is not an option")
        if not _option_ok(f, value):
            raise _Damaged(f"options.{key} is {_short(value)}, not {_option_kind(f)}")
    if options.get("size_field") is not None:  # (never a path to another file)
        raise _Damaged("options.size_field is set: a state keeps a size field's rows")
    if options.get("size") is not None:
        try:
            Expression(options["size"], "size")
        except OptionError as exc:
            raise _Damaged(f"options.size: {exc}") from None
    return options


def _option_kind(f) -> str:
    """What a recorded option must be, in words."""
    kind = f.metadata["kind"]
    return {
        "text": "a string",
        "path": "a string",
        "flag": "true or false",
        "switch": "true or false",
        "choice": "one of " + ", ".join(map(str, f.metadata.get("choices", ()))),
        "positive": "a finite number > 0",
        "float": "a finite number",
        "count": f"a whole number >= {f.metadata.get('min', 0)}",
        "box": "a box [XMIN, YMIN, XMAX, YMAX]",
        "vector": "a translation [DX, DY], not both 0",
    }[kind]


def _option_ok(f, v) -> bool:
    if v is None:  # (not set: only for an option whose default is not set either)
        return f.default is None
    if v == f.default and type(v) is type(f.default):
        return True
    kind = f.metadata["kind"]
    if kind in ("text", "path"):
        return isinstance(v, str)
    if kind in ("flag", "switch"):
        return isinstance(v, bool)
    if kind == "choice":
        return isinstance(v, str) and v in f.metadata["choices"]
    if kind == "positive":
        return _is_positive(v)
    if kind == "float":
        return _is_number(v)
    if kind == "count":
        return _is_count(v, f.metadata.get("min", 0))
    if kind == "box":
        return (isinstance(v, list) and len(v) == 4 and all(_is_coordinate(x) for x in v)
                and v[0] < v[2] and v[1] < v[3])  # fmt: skip
    if kind == "vector":
        return (isinstance(v, list) and len(v) == 2 and all(_is_coordinate(x) for x in v)
                and any(x != 0 for x in v))  # fmt: skip
    return False


def _graded_grid(g: dict, a: dict) -> GradedGrid:
    """The graded grid of a state file: its quadtree's leaves, triangulated again."""
    level, i, j = a["leaf_level"], a["leaf_i"], a["leaf_j"]
    top, nx, ny = g["top"], g["nx"], g["ny"]
    ok = (
        level.min() >= 0 and level.max() <= top
        and (i >= 0).all() and (j >= 0).all()
        and (i.astype(np.float64) * 2.0**level < nx * 2**top).all()
        and (j.astype(np.float64) * 2.0**level < ny * 2**top).all()
        and int((4.0 ** level.astype(np.float64)).sum()) == nx * ny * 4**top
    )  # fmt: skip
    if not ok:
        raise _Damaged("the graded grid's leaves do not tile its box")
    tree = Quadtree(
        float(g["x0"]), float(g["y0"]), float(g["hx"]), float(g["hy"]), top, nx, ny,
        level.astype(np.int64), i.astype(np.int64), j.astype(np.int64),
    )  # fmt: skip
    # leaves that cover the box's area and do not overlap tile it
    if tree.overlapping():
        raise _Damaged("the graded grid's leaves do not tile its box (leaves overlap)")
    return GradedGrid(tree, tree.triangulate()[0])
