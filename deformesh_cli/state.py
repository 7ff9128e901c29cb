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
import zipfile
from dataclasses import dataclass, field

import numpy as np

from . import __version__
from .contour import Contour, make_contour
from .errors import InputError, OptionError, WriteError
from .expression import Expression
from .select import Grid, Selection
from .select.graded import Quadtree
from .select.graded_path import GradedGrid, GradedSelection

FORMAT = "deformesh-state"
VERSION = 3
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
    #: the :class:`~.options.MeshOptions` fields of the stages run so far (their values)
    options: dict = field(default_factory=dict)


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
    if sel.path_slide is not None:
        arrays["path_slide"] = sel.path_slide
    if graded:
        arrays.update(leaf_level=g.tree.level, leaf_i=g.tree.i, leaf_j=g.tree.j)
    if state.stage == "deformed":
        arrays["points"] = state.points
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
    """Parse and check a state file; ``want`` is the stage the caller needs."""
    if not data:
        raise InputError(f"{name}: empty input, expected a deformesh state file")
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
        meta = json.loads(zf.read("meta.json"))
    except (zipfile.BadZipFile, KeyError, ValueError, EOFError):
        hint = " (truncated?)" if data[:2] == b"PK" else ""
        raise InputError(f"{name}: not a deformesh state file{hint}") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise InputError(f"{name}: not a deformesh state file (no '{FORMAT}' header)")
    if meta.get("version") != VERSION:
        raise InputError(
            f"{name}: state file version {meta.get('version')} (written by "
            f"{meta.get('written_by', 'unknown')}); this deformesh {__version__} reads "
            f"version {VERSION}: re-run 'deformesh select'"
        )
    stage = meta.get("stage")
    if stage not in STAGES:
        raise InputError(f"{name}: unknown stage {stage!r} in state file")
    if want is not None and stage != want:
        advice = {"selected": "deformesh select", "deformed": "deformesh deform"}[want]
        raise InputError(f"{name}: state is at stage '{stage}', expected '{want}' (from {advice})")
    spec = dict(_ARRAYS)
    if stage == "deformed":
        spec["points"] = ("f", 2, (2,))
    if "path_slide.npy" in zf.namelist():  # optional: an adapted grid's slide
        spec["path_slide"] = ("f", 2, (2,))
    graded = isinstance(meta.get("grid"), dict) and meta["grid"].get("kind") == "graded"
    if graded:  # the graded grid's leaves
        spec.update(leaf_level=("i", 1, ()), leaf_i=("i", 1, ()), leaf_j=("i", 1, ()))
    arrays = {}
    try:
        for key, (kind, ndim, tail) in spec.items():
            with zf.open(f"{key}.npy") as fh:
                a = np.lib.format.read_array(io.BytesIO(fh.read()))  # refuses objects
            if (
                a.dtype.kind not in (kind, "i" if kind == "u" else kind)
                or a.ndim != ndim
                or a.shape[1:] != tail
            ):
                raise InputError(f"{name}: damaged state file ({key}: wrong type or shape)")
            arrays[key] = a
        g = meta["grid"]
        if graded:
            grid = _graded_grid(g, arrays, name)
            cells = grid.tree.n_leaves
        else:
            grid = Grid(
                float(g["x0"]),
                float(g["y0"]),
                float(g["hx"]),
                float(g["hy"]),
                int(g["nx"]),
                int(g["ny"]),
            )
            cells = grid.nx * grid.ny
    except (KeyError, ValueError, TypeError, zipfile.BadZipFile, EOFError, OSError) as exc:
        raise InputError(f"{name}: damaged state file ({exc.__class__.__name__}: {exc})") from None
    n = grid.n_nodes
    p = len(arrays["path_nodes"])
    ok = (
        grid.nx >= 1
        and grid.ny >= 1
        and grid.hx > 0
        and grid.hy > 0
        and len(arrays["diagonals"]) == cells
        and len(arrays["path_targets"]) == p
        and len(arrays["path_source"]) == p
        and len(arrays["path_ring"]) == p
        and len(arrays.get("path_slide", arrays["path_ring"])) == p
        and p >= 3
        and arrays["path_nodes"].min() >= 0
        and arrays["path_nodes"].max() < n
        and len(arrays["contour_lines"]) == len(arrays["contour_points"])
        and (stage != "deformed" or arrays["points"].shape == (n, 2))
    )
    if not ok:
        raise InputError(f"{name}: inconsistent state file (array sizes do not match the grid)")
    starts = arrays["contour_starts"]
    if (
        len(starts) < 2
        or starts[0] != 0
        or starts[-1] != len(arrays["contour_points"])
        or (np.diff(starts) < 3).any()
    ):
        raise InputError(f"{name}: inconsistent state file (ring starts do not match the contour)")
    labels = meta.get("ring_labels")
    if labels is not None and (not isinstance(labels, list) or len(labels) != len(starts) - 1):
        raise InputError(f"{name}: inconsistent state file (ring_labels do not match the rings)")
    contour = make_contour(
        arrays["contour_points"],
        arrays["contour_lines"],
        str(meta.get("source", name)),
        ring_starts=starts[:-1],
        ring_labels=[str(x) for x in labels] if labels else None,
    )
    src = arrays["path_source"]
    if src.max() >= contour.n or np.count_nonzero(src >= 0) != contour.n:
        raise InputError(f"{name}: inconsistent state file (path does not match the contour)")
    if graded:
        sel = GradedSelection(
            grid,
            arrays["path_nodes"].astype(np.int64),
            arrays["path_targets"].astype(np.float64),
            src.astype(np.int64),
            arrays["path_ring"].astype(np.int64),
            arrays["diagonals"].astype(np.uint8),
            h=float(meta.get("h", grid.hx)),
            exterior=bool(meta.get("exterior", False)),
            notes=list(meta.get("notes", [])),
            h_rule=str(meta.get("h_rule", "graded")),
            path_slide=arrays.get("path_slide"),
        )
        return State(stage, contour, sel, arrays.get("points"), _options(meta, name))
    sel = Selection(
        grid=grid,
        path_nodes=arrays["path_nodes"].astype(np.int64),
        path_targets=arrays["path_targets"].astype(np.float64),
        path_source=src.astype(np.int64),
        diagonals=arrays["diagonals"].astype(np.uint8),
        h=float(meta.get("h", max(grid.hx, grid.hy))),
        h_rule=str(meta.get("h_rule", "given")),
        searched_further=int(meta.get("searched_further", 0)),
        refinements=int(meta.get("refinements", 0)),
        notes=list(meta.get("notes", [])),
        path_rule=str(meta.get("path_rule", "appendix-a")),
        path_ring=arrays["path_ring"].astype(np.int64),
        exterior=bool(meta.get("exterior", False)),
        path_slide=arrays.get("path_slide"),
    )
    return State(stage, contour, sel, arrays.get("points"), _options(meta, name))


def _options(meta: dict, name: str) -> dict:
    """The state's recorded options.  A size expression is data too: it is checked by the
    same parser as ``--size`` (never evaluated by Python), and refused as a bad state."""
    options = meta.get("options", {})
    if not isinstance(options, dict):
        raise InputError(f"{name}: inconsistent state file (options is not a mapping)")
    for key in ("size", "size_field"):
        if options.get(key) is not None and not isinstance(options[key], str):
            raise InputError(f"{name}: inconsistent state file (options.{key} is not a string)")
    if options.get("size") is not None:
        try:
            Expression(options["size"], "size")
        except OptionError as exc:
            raise InputError(f"{name}: the state file's {exc}") from None
    return options


def _graded_grid(g: dict, arrays: dict, name: str) -> GradedGrid:
    """The graded grid of a state file: its quadtree's leaves, triangulated again."""
    level, i, j = arrays["leaf_level"], arrays["leaf_i"], arrays["leaf_j"]
    top, nx, ny = int(g["top"]), int(g["nx"]), int(g["ny"])
    ok = (
        len(level) == len(i) == len(j) >= 1
        and min(top, nx, ny) >= 0 and nx >= 1 and ny >= 1 and top <= 60
        and float(g["hx"]) > 0 and float(g["hy"]) > 0
        and level.min() >= 0 and level.max() <= top
        and (i >= 0).all() and (j >= 0).all()
        and (i * 2**level < nx * 2**top).all() and (j * 2**level < ny * 2**top).all()
        and int((4.0 ** level.astype(np.float64)).sum()) == nx * ny * 4**top
    )  # fmt: skip
    if not ok:
        raise InputError(f"{name}: inconsistent state file (the graded grid's leaves)")
    tree = Quadtree(
        float(g["x0"]), float(g["y0"]), float(g["hx"]), float(g["hy"]), top, nx, ny,
        level.astype(np.int64), i.astype(np.int64), j.astype(np.int64),
    )  # fmt: skip
    return GradedGrid(tree, tree.triangulate()[0])
