"""The three stages chained: contour -> selection -> deformation -> mesh.

Each stage function here is what one subcommand runs; :func:`mesh_contour`
is what ``deformesh all`` runs.  Nothing here prints or exits.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from . import coarsen as _coarsen
from . import deadline, forced, geometry, quality, triangulate, untangle
from . import deform as _deform
from . import improve as _improve
from . import layers as _layers
from . import periodic as _periodic
from . import quads as _quads
from . import recover as _recover
from . import size as _size
from .contour import Contour, count_words, far_field_box, split_edges
from .deform import SOLVES, DeformStats
from .errors import (
    FoldError,
    LimitError,
    OptionError,
    SelectionError,
    SolverError,
    names_its_file,
)
from .geometry import next_on_ring
from .mesh import Mesh
from .options import MeshOptions
from .select import GRIDS, Selection, select
from .select import construct as _construct
from .size import SizeFunction

#: ``callback(done, stats)``: pseudo-time done (0 to 1) and the deformation's statistics.
Callback = Callable[[float, DeformStats], None]


@dataclass
class Deformed:
    """Stage 2 output: the selection plus the deformed node coordinates."""

    selection: Selection
    points: np.ndarray
    stats: DeformStats | None = None


@dataclass
class MeshResult:
    mesh: Mesh
    selection: Selection
    deform_stats: DeformStats | None
    report: dict = field(default_factory=dict)


def grid_mode(grid: str = "auto", h: float | None = None) -> str:
    """The grid a run lays: ``grid``, where ``auto`` is the graded grid (the uniform
    one with ``h``)."""
    if grid not in GRIDS:
        raise OptionError(f"--grid must be one of {', '.join(GRIDS)}, got {grid!r}")
    if grid == "graded" and h is not None:
        raise OptionError("--h sets the step of a uniform grid; it does not apply to --grid graded")
    if grid != "auto":
        return grid
    return "graded" if h is None else "uniform"


def _options(options: MeshOptions | None, changes: dict) -> MeshOptions:
    """``options`` (default: :class:`MeshOptions`'s defaults) with ``changes`` applied."""
    options = MeshOptions() if options is None else options
    return options.replace(**changes) if changes else options


@dataclass
class Laid:
    """The contour the grid is laid for, and how it relates to the one given.

    ``fine``: the given contour with its edges longer than ``--max-h`` split
    (:func:`.contour.split_edges`; the given points are ``fine``'s points ``given``,
    or None when nothing was split).  ``grid``: ``fine`` without the tips of its
    sharp empty ears on the graded grid (:func:`.construct.cut_ears`): grid point
    ``k`` is ``fine``'s point ``kept[k]``, and ``ears`` (previous, tip, next) come
    back as triangles once the boundary is recovered."""

    contour: Contour
    fine: Contour
    given: np.ndarray | None
    grid: Contour
    kept: np.ndarray | None = None
    ears: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=np.int64))

    @classmethod
    def as_is(cls, contour: Contour) -> Laid:
        """A contour the grid is laid for as it is: no edge split, no ear cut."""
        return cls(contour, contour, None, contour)

    def chords(self) -> set[tuple[int, int]]:
        """The pairs of ``grid`` points joined by an edge of ``grid`` that is not one of
        ``fine``'s: the chords the cut ears stand on (a cut tip's: between its two
        points)."""
        if self.kept is None:
            return set()
        g, m = self.grid, self.fine.n
        a = np.arange(g.n)
        b = next_on_ring(g.ring)
        fine_next = np.append(next_on_ring(self.fine.ring), -1)  # (-1: an added point's)
        ka, kb = self.kept[a], self.kept[b]
        fa, fb = np.where(ka < m, ka, m), np.where(kb < m, kb, m)
        chord = np.where(
            (ka >= m) | (kb >= m),
            (ka >= m) & (kb >= m),
            (fine_next[fa] != kb) & (fine_next[fb] != ka),
        )
        return set(zip(a[chord].tolist(), b[chord].tolist()))


@names_its_file
def lay(contour: Contour, o: MeshOptions, graded: bool | None = None) -> Laid:
    """:class:`Laid` for ``contour`` under options ``o`` (``graded``: the grid is the
    graded one; default: as ``o`` asks)."""
    if o.max_h is not None:
        _check_max_h_work(contour, o)
    fine, given = split_edges(contour, o.max_h, o.max_nodes)
    if graded is None:
        graded = grid_mode(o.grid, o.h) == "graded"
    if not graded:
        return Laid(contour, fine, given, fine)
    grid, kept, ears = _construct.cut_ears(fine, o.exterior)
    return Laid(contour, fine, given, grid, kept, ears)


def _check_max_h_work(contour: Contour, o: MeshOptions) -> None:
    """Refuse, before any work, a ``--max-h`` whose mesh cannot fit ``--max-nodes``: a
    triangle whose sides are at most ``H`` covers at most ``sqrt(3)/4 H^2``, so a domain
    of area ``A`` needs at least ``A / (sqrt(3)/4 H^2)`` triangles, and a triangulation
    has at least half as many nodes as triangles."""
    if o.exterior:
        x0, y0, x1, y1 = o.box if o.box is not None else far_field_box(contour, o.margin)
        area = (x1 - x0) * (y1 - y0) - contour.area
    else:
        area = contour.area
    with np.errstate(over="ignore"):  # (a tiny H: inf, refused below)
        nodes = float(np.float64(area) / o.max_h / o.max_h / (3.0**0.5 / 4.0) / 2.0)
    if not nodes <= o.max_nodes:
        raise LimitError(
            f"{contour.source}: --max-h {o.max_h:g} needs at least {count_words(nodes)} "
            f"nodes for its area {area:.3g}, over --max-nodes {o.max_nodes:,}; give a "
            "larger --max-h"
        )


@names_its_file
def run_select(
    contour: Contour,
    options: MeshOptions | None = None,
    *,
    size_function: SizeFunction | None = None,
    **changes,
) -> Selection:
    """Stage 1 on ``contour`` (a :class:`Laid`'s ``grid``; the options' select fields).

    The graded grid is constructed (:func:`.construct.select_constructed`), its cells
    also following the size function (``size_function``, else the options' ``size``
    or ``size_field``).  Appendix A's uniform grid searches its path for at most
    :func:`.deadline.search_bound` seconds, and is refused past it."""
    o = _options(options, changes)
    if grid_mode(o.grid, o.h) == "graded":
        size = size_function or _size.make(o.size, o.size_field, contour)
        return _construct.select_constructed(
            contour,
            box=o.box,
            margin=o.margin,
            exterior=o.exterior,
            growth=o.growth,
            max_nodes=o.max_nodes,
            max_h=o.max_h,
            size_function=size,
            periodic=o.periodic,
        )
    try:
        with deadline.limit(deadline.search_bound(contour.n)):
            return select(
                contour,
                h=o.h,
                box=o.box,
                margin=o.margin,
                strict=o.strict,
                max_nodes=o.max_nodes,
                exterior=o.exterior,
            )
    except deadline.TimeUp as exc:
        raise LimitError(
            f"{contour.source}: {exc} ({contour.n} points); simplify the contour, "
            "re-space it (--resample) or give --grid graded"
        ) from None


@names_its_file
def run_deform(
    contour: Contour,
    sel: Selection,
    options: MeshOptions | None = None,
    *,
    callback: Callback | None = None,
    size_function: SizeFunction | None = None,
    keep_folds: bool | None = None,
    **changes,
) -> Deformed:
    """Stage 2 (the options' deform fields).  The size function (``size_function``, else
    the one the options' ``size`` or ``size_field`` give; normalised here over the
    grid's box) shapes the cells.

    ``solve="band"`` moves only the cells near the path (the selection's ``band_nodes``),
    unless a size function is given (it shapes every cell) or the band would
    cover half the grid; ``"full"`` solves on the whole grid.  On the graded grid
    only the domain's side of the path is solved for (:func:`.deform.deform_band`'s
    ``kept``): the other side's triangles are dropped, and a fold there does not stop
    the deformation; a size function there takes the cells from the grid's own
    density to its own (:func:`_domain_size_path`).

    ``keep_folds`` (default: the selection's ``mends_folds``): a fold that cannot be
    avoided does not stop the deformation (:func:`.deform.deform_`);
    the stats' ``fold`` then says where it first folded, and stage 3 mends the mesh
    (:mod:`.untangle`).  A deformation that cannot go on at all still raises
    :class:`FoldError`.
    """
    o = _options(options, changes)
    if keep_folds is None:
        keep_folds = sel.mends_folds
    if o.solve not in SOLVES:
        raise OptionError(f"--solve must be one of {', '.join(SOLVES)}, got {o.solve!r}")
    size = size_function
    if size is None:
        size = _size.make(o.size, o.size_field, contour)
    grid = sel.grid
    pts0 = grid.coords()
    tri = sel.triangles()
    if size is not None:
        size.normalise(grid.box)
    band = sel.band_nodes() if o.solve == "band" and size is None else None
    kwargs = {
        "steps": o.steps,
        "callback": callback,
        "describe": _describer(contour, sel),
        "solver": o.solver,
        "keep_folds": keep_folds,
    }
    args = (pts0, tri, sel.path_nodes, sel.path_targets, sel.held_nodes())
    try:
        if sel.mends_folds:  # (the domain's side only; stage 3 meshes flat triangles again)
            kept = sel.kept_triangles()
            path = None if size is None else _domain_size_path(pts0, tri[kept], size, grid.box)
            pos, st = _deform.deform_band(*args, band, kept=kept, size=path, flat_ok=True, **kwargs)
        else:  # (the uniform grid: both sides, toward f from uniform cells)
            path = None if size is None else _size.SizePath(size.g1, grid.box)
            if band is None:
                pos, st = _deform.deform(*args, size=path, **kwargs)
            else:
                pos, st = _deform.deform_band(*args, band, size=path, **kwargs)
    except SolverError as exc:
        raise SolverError(f"{contour.source}: deformation failed: {exc}") from None
    if st.fold is not None and not np.isfinite(pos).all():
        raise FoldError(st.fold)
    return Deformed(sel, pos, st)


def _domain_size_path(points: np.ndarray, kept: np.ndarray, size: SizeFunction, box):
    """The graded grid's way to a size function: from the grid's own density
    (:func:`.size.grid_density` of the domain's triangles ``kept``) to ``size``'s, kept
    within :data:`.size.MAX_DENSITY_RATIO` of it (:func:`.size.limited_target`: the
    quadtree already follows ``f`` to a factor of 4 in area; asked for more, the cells
    by the contour, which its points hold, fold against it), both scaled to integrate
    to the domain's area over it.  The path nodes close the domain, so the
    deformation keeps its area (div U integrates to zero over it)."""
    g0 = _size.grid_density(points, kept, box)
    g1 = _size.limited_target(size.g1, g0, box)
    cen = points[kept].mean(axis=1)
    area = np.abs(geometry.signed_areas(points, kept))
    c0 = float(area @ g0(cen) / area.sum())
    c1 = float(area @ g1(cen) / area.sum())
    return _size.SizePath(lambda q: g1(q) / c1, box, g0=lambda q: g0(q) / c0)


def _describer(contour: Contour, sel: Selection):
    src = sel.path_source
    nodes = sel.path_nodes

    def describe(tri_nodes) -> str:
        hit = np.flatnonzero(np.isin(nodes, tri_nodes) & (src >= 0))
        if len(hit) == 0:
            return ""
        return f" (by contour {contour.where(int(src[hit[0]]))})"

    return describe


@names_its_file
def run_triangulate(
    laid: Laid,
    d: Deformed,
    options: MeshOptions | None = None,
    *,
    size_function: SizeFunction | None = None,
    cut: triangulate.Cut | None = None,
    **changes,
) -> tuple[Mesh, dict]:
    """Stage 3: the mesh of the deformed grid and its summary, in order: the kept
    triangles at the deformed points, folded ones meshed again (:mod:`.untangle`, a
    graded grid's), the extra boundary nodes taken out (:mod:`.recover`, unless
    ``merge_extra`` keeps them), the ears cut before the grid was laid added back,
    the quality stage once (the options' ``improve``), the contract checked, the
    given points numbered first (with ``--max-h``).  ``laid``: from :func:`lay`, or
    :meth:`Laid.as_is` for a contour the grid was laid for as it is.  ``cut``:
    :func:`.triangulate.cut` of this selection, if already made."""
    o = _options(options, changes)
    sel = d.selection
    size = size_function
    if size is None:
        size = _size.make(o.size, o.size_field, laid.contour)
    contour = laid.grid
    if cut is None:
        cut = triangulate.cut(contour, sel)
    mesh = triangulate.place(contour, sel, cut, d.points, folded=sel.mends_folds)
    edges = cut.edges  # (the contract check's edge uses, while they stay true)
    if sel.mends_folds:
        mended, where = untangle.mend(mesh, untangle.most_tangled(mesh))
        if mended is None:
            raise FoldError(
                f"{contour.source}: the deformed grid has a folded or flat triangle near "
                f"({where[0]:.6g}, {where[1]:.6g}) that could not be meshed again"
            )
        if mended is not mesh:
            sel.notes.append("folded or flat triangles of the deformed grid were meshed again")
            mesh, edges = mended, None
    recovered = 0
    if mesh.n_extra and (_recovers(o) or len(laid.ears)):
        # (an ear comes back on its chord: the chord's run goes even where the rest stay)
        mesh, recovered = _recover.recover(mesh, None if _recovers(o) else laid.chords())
        edges = None if recovered else edges
    if o.strict and mesh.n_extra:
        raise SelectionError(
            f"{contour.source}: {mesh.n_extra} extra boundary nodes left and --strict given"
        )
    if len(laid.ears):
        mesh = _construct.restore_ears(mesh, laid.fine, laid.kept, laid.ears, o.exterior)
        edges = None
        if mesh.n_extra and _recovers(o):  # (the points of the tips cut)
            mesh, more = _recover.recover(mesh)
            recovered += more
    # the interior taken to the size field the grid was laid for (none on the uniform
    # grid; none with a size function, which the deformation follows)
    sizes = None
    if size is None:  # (an exterior mesh's box as the selection saw it)
        box = _construct.exterior_box(contour, o.box, o.margin) if sel.exterior else None
        sizes = sel.size_field(contour, o.growth, o.max_h, o.max_nodes, box)
    coarsened = 0
    if sizes is not None:
        mesh, coarsened = _coarsen.coarsen(mesh, sizes)
        edges = None if coarsened else edges
    better = None
    if o.improve:
        before = mesh
        mesh, better = _improve.improve(mesh)
        if len(better.changed) and edges is not None:  # the changed triangles' edges
            old = len(before.triangles)
            edges = geometry.patch_edge_uses(
                edges,
                mesh.n_nodes,
                before.triangles[better.changed],
                np.concatenate([mesh.triangles[better.changed], mesh.triangles[old:]]),
            )
    box = sel.grid.box if sel.exterior else None
    # the contract check and the summary read the mesh independently; numpy and
    # scipy release the GIL in their loops, so on two cores the pair takes about as
    # long as the longer one (``benchmarks/MEASURED.md``)
    with ThreadPoolExecutor(max_workers=2) as pool:
        summary = pool.submit(quality.stats, mesh)
        quality.check_contract(mesh, laid.fine, box, edges)
        report = summary.result()
    report["contract"] = "ok"
    report["recovered_extra_nodes"] = int(recovered)
    report["ears"] = int(len(laid.ears))
    report["coarsened_nodes"] = int(coarsened)
    report["improve"] = (
        None
        if better is None
        else {
            "min_angle_before": better.min_angle_before,
            "flips": better.flips,
            "node_moves": better.moves,
            "nodes_added": better.added,
            "rounds": better.rounds,
        }
    )
    # what the boundary nodes allow next to the triangles under 30 degrees (README, "What
    # the boundary forces"), if any
    report["forced_angle"] = None
    if report["min_angle"] < 30:
        weak = (
            better.weak
            if better is not None
            else np.flatnonzero(quality.measures(mesh.points, mesh.triangles)[0] < 30)
        )
        report["forced_angle"] = forced.weakest_bound(mesh.points, mesh.triangles, mesh.lines, weak)
    note = forced_note(mesh, report) if o.max_h is None else None
    if note is not None and note not in sel.notes:  # (the summary's notes are the selection's)
        sel.notes.append(note)
    if size is not None:
        report["size"] = size.label
        rho = _size.spearman(mesh.points, mesh.triangles, size, exclude=mesh.lines.ravel())
        report["size_correlation"] = None if np.isnan(rho) else rho
    if laid.given is not None:
        mesh, report = given_first(mesh, report, laid.contour, laid.fine, laid.given, box)
    return mesh, report


def _recovers(o: MeshOptions) -> bool:
    """Whether stage 3 takes the extra boundary nodes out (``merge_extra``; ``auto``:
    not on the uniform grid, the paper's form)."""
    if o.merge_extra != "auto":
        return o.merge_extra == "merge"
    return not _paper_form(o)


def _paper_form(o: MeshOptions) -> bool:
    """Appendix A's uniform grid asked for (``--grid uniform`` or ``--h``): its meshes
    stay as the paper builds them (extra boundary nodes kept)."""
    return o.grid == "uniform" or o.h is not None


@names_its_file
def mesh_contour(
    contour: Contour,
    options: MeshOptions | None = None,
    *,
    callback: Callback | None = None,
    size_function: SizeFunction | None = None,
    seconds: dict | None = None,
    on_stage: Callable[[str], None] | None = None,
    **changes,
) -> MeshResult:
    """Mesh the inside of ``contour`` (or the box minus it, ``exterior``): the
    contour laid (:func:`lay`), selected, deformed, triangulated, one call each.

    ``options`` (default: :class:`~.options.MeshOptions`' defaults) with
    ``changes`` (its field names: ``mesh_contour(c, exterior=True)``);
    ``callback(done, stats)`` follows the deformation; ``on_stage(name)`` is called as
    each stage starts (``layers``, ``select``, ``deform``, ``triangulate``);
    ``size_function`` replaces the options' ``size`` and ``size_field``.  ``seconds``:
    filled with each stage's time as it ends (for the benchmarks; nothing reads them).
    The result meets the contract or this raises.

    With boundary layers (:mod:`.layers`): the stacks grown from the walls' points,
    the rest of the domain meshed as a contour of their top nodes (with the options'
    other fields, extra boundary nodes taken out on any grid), the two joined and
    checked, then finished as one mesh.
    """
    o = _options(options, changes)
    stacks = None
    if o.layers:
        if on_stage is not None:
            on_stage("layers")
        stacks = grow_layers(contour, o)
    res = _mesh_of(
        contour if stacks is None else stacks.top,
        o if stacks is None else core_options(o),
        callback=callback,
        size_function=size_function,
        seconds=seconds,
        on_stage=on_stage,
    )
    if stacks is not None:
        res.mesh, res.report = join_layers(contour, stacks, res.mesh, res.report, res.selection, o)
    box = res.selection.grid.box if o.exterior else None
    res.mesh, res.report = finish_mesh(contour, res.mesh, res.report, o, box, stacks)
    return res


def _mesh_of(
    contour: Contour,
    o: MeshOptions,
    *,
    callback: Callback | None = None,
    size_function: SizeFunction | None = None,
    seconds: dict | None = None,
    on_stage: Callable[[str], None] | None = None,
) -> MeshResult:
    """The three stages on ``contour``, no layers: its triangle mesh, before
    :func:`finish_mesh`."""
    stage = on_stage or (lambda name: None)
    seconds = {} if seconds is None else seconds
    size = size_function
    if size is None:
        size = _size.make(o.size, o.size_field, contour)
    start = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal start
        now = time.perf_counter()
        seconds[stage], start = now - start, now

    stage("select")
    laid = lay(contour, o)
    sel = run_select(laid.grid, o, size_function=size)
    lap("select")
    stage("deform")
    sel.triangles()  # built once, here, rather than by both threads at once
    sel.kept_triangles()
    # stage 3's topology (which triangles, numbered how, and their edges) needs only
    # the selection: it runs on the second core while the deformation runs
    # (``benchmarks/MEASURED.md``)
    with ThreadPoolExecutor(max_workers=1) as pool:
        cut = pool.submit(triangulate.cut, laid.grid, sel, edges=True)
        d = run_deform(laid.grid, sel, o, callback=callback, size_function=size)
        lap("deform")
        stage("triangulate")
        mesh, report = run_triangulate(laid, d, o, size_function=size, cut=cut.result())
    lap("triangulate")
    report.update(selection_report(sel))
    if d.stats is not None:
        report["moved_nodes"] = int(d.stats.moved_nodes)  # the band's nodes, or every node
    return MeshResult(mesh, sel, d.stats, report)


def finish_mesh(
    contour: Contour, mesh: Mesh, report: dict, o: MeshOptions, box=None, stacks=None
) -> tuple[Mesh, dict]:
    """The last steps on a checked mesh (``stacks``: its boundary layers, joined by
    :func:`join_layers`): the cells ``o.cells`` asks for (:func:`shape_cells`), then
    the periodic pairs ``o.periodic`` asks for (:func:`.periodic.pair`: the mesh's
    ``periodic`` and point data ``periodic``, each node's partner or -1; the summary's
    ``periodic`` record)."""
    mesh, report = shape_cells(contour, mesh, report, o, box, stacks)
    if o.periodic is None:
        return mesh, report
    pairs = _periodic.pair(mesh, o.periodic, contour.source)
    data = {**mesh.point_data, "periodic": _periodic.partner_data(mesh.n_nodes, pairs)}
    mesh = dataclasses.replace(mesh, periodic=pairs, shift=tuple(o.periodic), point_data=data)
    report = {**report, "periodic": {"shift": list(o.periodic), "pairs": int(len(pairs))}}
    return mesh, report


def shape_cells(
    contour: Contour, mesh: Mesh, report: dict, o: MeshOptions, box=None, stacks=None
) -> tuple[Mesh, dict]:
    """The cells ``o.cells`` asks for (:mod:`.quads`) on the finished ``mesh`` of
    ``contour`` (``box``: an exterior mesh's; ``stacks``: its boundary layers, whose
    rays ``quad-only`` keeps whole), checked, and its summary with the quads' record:
    ``tri`` leaves both as they are."""
    if o.cells == "tri":
        return mesh, report
    if o.cells not in _quads.CELLS:
        raise OptionError(f"--cells must be one of {', '.join(_quads.CELLS)}, got {o.cells!r}")
    mesh, made = _quads.recombine(mesh)
    report = {**report, "cells": o.cells, "quads_made": made}
    if o.cells == "quad-only":
        columns = None if stacks is None else _layers.columns(stacks, mesh)
        mesh, added = _quads.subdivide(mesh, triangulate.BOX_SIDES, columns)
        report["split_boundary_edges"] = added
        report["notes"] = [
            *report.get("notes", []),
            f"--cells quad-only put a node at the middle of each of the {added} boundary "
            "edges (after the given points)",
        ]
    quality.check_contract(mesh, contour, box)
    stats = quality.stats(mesh)
    report.update(stats)
    return mesh, report


def layer_spec(contour: Contour, o: MeshOptions) -> _layers.LayerSpec:
    """The boundary layers ``o`` asks for on ``contour``: ``--layers-on`` names the
    rings by their boundary groups (``contour``, ``contour_2``, ``hole_1``, ...)."""
    if o.first_height is None:
        raise OptionError("--layers needs --first-height (the first layer's height)")
    check_layer_cells(o)
    if o.max_h is not None:
        raise OptionError(
            "--max-h would split the walls' edges under the layers; give --layers without it"
        )
    rings = None
    if o.layers_on is not None:
        names = {contour.ring_name(r): r for r in range(contour.n_rings)}
        wanted = [w.strip() for w in o.layers_on.split(",") if w.strip()]
        unknown = [w for w in wanted if w not in names]
        if unknown or not wanted:
            raise OptionError(
                f"{contour.source}: --layers-on names {', '.join(unknown) or 'no group'}; "
                f"its rings are {', '.join(names)} (the box's sides never have layers)"
            )
        rings = tuple(sorted({names[w] for w in wanted}))
    return _layers.LayerSpec(o.layers, o.first_height, o.layer_growth, rings)


def check_layer_cells(o: MeshOptions) -> None:
    """Refuse ``--cells quad`` or ``quad-only`` with ``--layer-cells tri``: the layers
    split into triangles would be made quads again."""
    if o.cells != "tri" and o.layer_cells == "tri":
        raise OptionError(
            f"--cells {o.cells} would make quads again of the layers --layer-cells tri "
            "splits into triangles; give one of them"
        )


@names_its_file
def grow_layers(contour: Contour, o: MeshOptions) -> _layers.Stacks:
    """The boundary layers ``o`` asks for on ``contour`` (:func:`.layers.build`; an
    exterior mesh's stacks bounded by its far-field box, that of the body without its
    layers when none is given)."""
    spec = layer_spec(contour, o)
    if o.merge_extra == "keep":
        raise OptionError(
            "--merge-extra keep would leave grid nodes between the layers' top nodes; "
            "the layers need them taken out (merge, which --layers does on any grid)"
        )
    box = _construct.exterior_box(contour, o.box, o.margin) if o.exterior else None
    return _layers.build(contour, spec, o.exterior, box, o.max_nodes)


def core_options(o: MeshOptions) -> MeshOptions:
    """The options the rest of the domain is meshed with under layers: no layers of its
    own, and extra boundary nodes taken out on any grid (the top nodes its only
    boundary nodes).  Its cells and periodic pairs are the whole mesh's
    (:func:`finish_mesh`, after the layers are joined)."""
    return o.replace(layers=0, merge_extra="merge")


def join_layers(
    contour: Contour, stacks, core: Mesh, core_report: dict, sel: Selection, o: MeshOptions
) -> tuple[Mesh, dict]:
    """The mesh of ``contour``: the layer cells of ``stacks`` and ``core`` (the mesh of
    their top, meshed on ``sel``), split as ``o.layer_cells`` asks, checked; and its
    summary."""
    mesh = _layers.combine(contour, stacks, core, o.exterior)
    layers = _layers.summary(stacks, mesh)  # (measured on the quads)
    if o.layer_cells == "tri":
        mesh = _layers.split_quads(mesh)
    quality.check_contract(mesh, contour, sel.grid.box if o.exterior else None)
    report = {**core_report, **quality.stats(mesh), "contract": "ok", "layers": layers}
    return mesh, report


#: A mesh whose smallest angle is under this (degrees) gets a note: what its boundary
#: nodes force, and the ``--max-h`` that lifts it where long edges force it.
NOTE_BELOW = 10.0


def forced_note(mesh: Mesh, report: dict) -> str | None:
    """Where the smallest angle is under :data:`NOTE_BELOW`: the note naming what the
    given points force (the report's ``forced_angle``) and, where an edge forces an
    angle under 30 degrees for want of room beside it (not a corner: its forced angle
    is under its corners'), the ``--max-h`` that lifts it: the room beside the
    tightest such edge, ``(L / 2) tan F``, so that its pieces have an isosceles of
    45 degrees in the domain."""
    if report["min_angle"] >= NOTE_BELOW:
        return None
    pts, lines = mesh.points, mesh.lines
    f = forced.edge_angles(pts, lines, forced.mesh_domain(pts, lines))
    _, corner = forced.corner_angles(pts, lines)
    at_corner = np.minimum(corner[lines[:, 0]], corner[lines[:, 1]])
    length = np.hypot(*(pts[lines[:, 1]] - pts[lines[:, 0]]).T)
    roomy = (f < 30) & (f < np.minimum(at_corner, 60) - 1e-6)
    bound = report.get("forced_angle")
    what = f"the smallest angle is {report['min_angle']:.1f} deg"
    if bound is not None:
        what += f"; no mesh on exactly these boundary nodes has more than {bound:.1f} there"
    if not roomy.any():
        return f"{what} (a sharp corner of the contour forces it)"
    h = float((0.5 * length[roomy] * np.tan(np.radians(f[roomy]))).min())
    return f"{what}: long edges with little room beside them; --max-h {h:.3g} splits them"


def given_first(
    mesh: Mesh, report: dict, contour: Contour, fine: Contour, given: np.ndarray, box
) -> tuple[Mesh, dict]:
    """A mesh of ``fine`` (``contour`` with edges split) renumbered as the contract wants
    for ``contour``: its given points are nodes ``0 .. m-1``, then every other boundary
    node on the rings (the split points and any extra node) in boundary order, then the
    rest as they were; checked against ``contour``.  The report counts the split
    points as extra boundary nodes (``split_nodes`` of them)."""
    m, big = contour.n, fine.n + mesh.n_extra
    first = np.full(mesh.n_nodes, -1, dtype=np.int64)
    first[given] = np.arange(m)
    walk = mesh.lines[:, 0]
    on_ring = walk[(walk < big) & (first[walk] < 0)]
    _, at = np.unique(on_ring, return_index=True)
    extra = on_ring[np.sort(at)]  # (in boundary order)
    perm = np.concatenate([given, extra, np.arange(big, mesh.n_nodes)])
    inv = np.empty_like(perm)
    inv[perm] = np.arange(len(perm))
    out = Mesh(
        mesh.points[perm],
        inv[mesh.triangles],
        inv[mesh.lines],
        n_contour=m,
        n_extra=len(extra),
        line_group=mesh.line_group,
        groups=mesh.groups,
        n_box=mesh.n_box,
        point_data={k: v[perm] for k, v in mesh.point_data.items()},
    )
    quality.check_contract(out, contour, box)
    added = fine.n - m
    report = {**report, "extra_boundary_nodes": len(extra), "split_nodes": added}
    report["notes"] = [
        *report.get("notes", []),
        f"--max-h split the contour's edges longer than it: {added} boundary nodes added "
        f"(nodes {m} to {m + added - 1}, after the given points)",
    ]
    return out, report


def selection_report(sel: Selection) -> dict:
    g = sel.grid
    return {
        "h": float(sel.h),
        "h_rule": sel.h_rule,
        "grid": [int(g.nx), int(g.ny)],
        "grid_nodes": int(g.n_nodes),
        "box": [float(v) for v in g.box],
        "searched_further": int(sel.searched_further),
        "refinements": int(sel.refinements),
        "path_rule": sel.path_rule,
        "exterior": bool(sel.exterior),
        "notes": list(sel.notes),
    }
