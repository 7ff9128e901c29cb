"""The three stages chained: contour -> selection -> deformation -> mesh.

Each stage function here is what one subcommand runs; :func:`mesh_contour`
is what ``deformesh all`` runs.  Nothing here prints or exits.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from . import deadline, forced, geometry, quality, triangulate, untangle
from . import deform as _deform
from . import improve as _improve
from . import merge as _merge
from . import recover as _recover
from . import size as _size
from .contour import Contour, split_edges
from .deform import SOLVES, DeformStats
from .errors import (
    ContractError,
    FoldError,
    LimitError,
    OptionError,
    SelectionError,
    SolverError,
)
from .mesh import Mesh
from .options import MeshOptions
from .select import EVEN_SPACING_RATIO, GRIDS, Selection, select
from .select import construct as _construct
from .select import respace as _respace
from .select.graded_path import GradedSelection, select_graded
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


def grid_mode(
    contour: Contour, grid: str = "auto", h: float | None = None, exterior: bool = False
) -> str:
    """The grid ``all`` lays first: ``grid``, where ``auto`` is the graded grid (the
    uniform one with ``h``)."""
    if grid not in GRIDS:
        raise OptionError(f"--grid must be one of {', '.join(GRIDS)}, got {grid!r}")
    if grid == "graded" and h is not None:
        raise OptionError("--h sets the step of a uniform grid; it does not apply to --grid graded")
    if grid != "auto":
        return grid
    return "graded" if h is None else "uniform"


def fallback_mode(contour: Contour, exterior: bool = False) -> str:
    """The graded grid's fallback where it finds no path: the adapted grid when the
    median spacing is over :data:`EVEN_SPACING_RATIO` times the smallest (and not a far
    field), else the uniform one."""
    if exterior:
        return "uniform"
    return "adapt" if _respace.spacing_ratio(contour) > EVEN_SPACING_RATIO else "uniform"


#: The graded grid's selections, tried in this order (:func:`.select_graded`'s ways):
#: the points as given, evenly re-spaced and slid, slid to a grid fitted to them; then
#: the same with extra boundary nodes where a contour edge crosses more cells than one
#: step can (unless ``--strict``), for stage 3 to merge out again.
GRADED_ATTEMPTS = (
    {},
    {"slide": True},
    {"fit": True},
    {"extra": True},
    {"slide": True, "extra": True},
    {"fit": True, "extra": True},
)


#: :data:`GRADED_ATTEMPTS` for a contour that stops at its first mesh
#: (:func:`_tries_every_way`) of at most :data:`LARGE_ORDER_POINTS` points: the
#: fitted grid, which costs most to lay, after the points as given with extra
#: nodes.  On the corpus it never had a path without extra nodes on such a
#: contour, and the largest coastline spent 0.3-0.5 s laying it (``benchmarks/MEASURED.md``).
GRADED_ATTEMPTS_FIRST = (
    {},
    {"slide": True},
    {"extra": True},
    {"fit": True},
    {"slide": True, "extra": True},
    {"fit": True, "extra": True},
)


#: :data:`GRADED_ATTEMPTS` for a contour of more than :data:`LARGE_ORDER_POINTS` points:
#: the points as given with extra nodes comes second, before the slid and fitted grids
#: without.  Such a contour stops at the first mesh with no extra node left that keeps
#: the bound, and on the corpus's large coastlines the slid and fitted grids never had
#: a path without extra nodes where that one meshed; laying them cost a third of the
#: run (1.2 s of 3.6 s on one, ``benchmarks/MEASURED.md``).
GRADED_ATTEMPTS_LARGE = (
    {},
    {"extra": True},
    {"slide": True},
    {"fit": True},
    {"slide": True, "extra": True},
    {"fit": True, "extra": True},
)


#: ``all`` keeps a graded mesh whose extra boundary nodes did not all merge, without
#: trying the fallback grid, when they are at most this share of the contour's points
#: (the fallback grids split more edges on every corpus contour measured, and their
#: first rung alone took 6.6 s on a coastline: ``benchmarks/MEASURED.md``).
EXTRA_ENOUGH = 0.02


#: A fallback grid's selection with more extra boundary nodes than this many per
#: contour point is not meshed (``all`` goes on to the next, or refuses): on combs and
#: spikes the uniform grid's path took 100 to 1,500 a point, and their meshes of up to
#: 9e6 triangles 20 to 60 s (``benchmarks/MEASURED.md``).  ``--grid uniform`` meshes
#: them still.
MAX_FALLBACK_EXTRA = 100


#: A contour of at most this many points tries every graded way with extra nodes
#: and keeps the best mesh, even after one with none left; a larger one stops there,
#: and mends a way that folded at once.  The other ways cost about as much as the
#: first again and, on the corpus, gained something only below 400 points
#: (an icon of 374: 13.2 -> 13.8 degrees); coastlines of 452 and 993 points spent
#: 1 s and 2.5 s on ways that gave no mesh or folded before the first was mended,
#: the mesh kept.  A threshold tuned on the corpus (``benchmarks/MEASURED.md``).
EXTRA_WAYS_POINTS = 400


#: A contour of more than this many points tries its ways in the order of
#: :data:`GRADED_ATTEMPTS_LARGE`.
LARGE_ORDER_POINTS = 1000


def _tries_every_way(contour: Contour) -> bool:
    """Whether ``contour`` is small enough to try every graded way
    (:data:`EXTRA_WAYS_POINTS`); a larger one stops at the first mesh with no extra
    node left that keeps the bound, and mends a fold at once."""
    return contour.n <= EXTRA_WAYS_POINTS


def _options(options: MeshOptions | None, changes: dict) -> MeshOptions:
    """``options`` (default: :class:`MeshOptions`'s defaults) with ``changes`` applied."""
    options = MeshOptions() if options is None else options
    return options.replace(**changes) if changes else options


def candidate_selections(
    contour: Contour,
    options: MeshOptions | None = None,
    *,
    size_function: SizeFunction | None = None,
    fall_back: Callable[[], bool] | None = None,
    mend: list[GradedSelection] | None = None,
    **changes,
) -> Iterator[Selection]:
    """The selections ``all`` tries in turn.

    On an adapted grid: the re-spaced ones (:func:`.respace.candidate_selections`),
    then, if none could be selected or all of them folded, Appendix A's uniform grid
    (whose errors are the ones reported).  ``changes``: :class:`MeshOptions` fields.
    The graded grid is refined for the size function (``size_function``, else the
    options' ``size`` or ``size_field``).  ``fall_back()``, asked once the graded
    grid's selections are done, says whether to go on to the fallback grid.
    ``mend``: the graded selections whose deformation folded, listed by the caller
    as it goes; if ``fall_back()`` asks for more, they are yielded again, for the
    caller to deform keeping the folds and mend them (:mod:`.untangle`): once the
    graded ways are done, or, for a contour too large to try every way
    (:func:`_tries_every_way`), each one right after it folded.
    """
    o = _options(options, changes)
    mode = grid_mode(contour, o.grid, o.h, o.exterior)
    if mode != "graded":
        yield from _ungraded(contour, o, mode)
        return
    size = size_function or _size.make(o.size, o.size_field, contour)
    grids: dict = {}  # each way's grid, laid once for it with and without extra nodes

    def graded(attempt: dict) -> GradedSelection:
        return select_graded(
            contour,
            box=o.box,
            margin=o.margin,
            exterior=o.exterior,
            max_nodes=o.max_nodes,
            growth=o.growth,
            max_h=o.max_h,
            size=size,
            cache=grids,
            **attempt,
        )

    # as given, slid, fitted to the points; then with extra boundary nodes
    every = _tries_every_way(contour)
    if contour.n > LARGE_ORDER_POINTS:
        order = GRADED_ATTEMPTS_LARGE
    else:
        order = GRADED_ATTEMPTS if every else GRADED_ATTEMPTS_FIRST
    attempts = [a for a in order if not (o.strict and a.get("extra"))]
    fell_back = None
    for attempt in attempts:
        deadline.check()
        try:
            sel = graded(attempt)
        except (SelectionError, LimitError) as exc:
            why = str(exc).removeprefix(f"{contour.source}: ")
            fell_back = f"the graded grid did not work here ({why})"
            continue
        if sel.extra_nodes:
            sel.notes.insert(0, f"{fell_back}; with extra boundary nodes on the graded grid")
        yield sel
        fell_back = "the graded grid's deformation folded"
        if not every and mend and mend[-1] is sel and (fall_back is None or fall_back()):
            yield sel  # (a large contour keeps its first good mesh: its folds mended now)
    if every and mend and (fall_back is None or fall_back()):
        yield from list(mend)
    if fall_back is not None and not fall_back():
        return
    mode = fallback_mode(contour, o.exterior)
    grid = {"adapt": "adapted"}.get(mode, mode)
    too_many = None
    try:
        for sel in _ungraded(contour, o, mode):
            if sel.extra_nodes > MAX_FALLBACK_EXTRA * contour.n:
                kind = "adapted" if sel.h_rule == _respace.ADAPTED else "uniform"
                too_many = too_many or (kind, sel.extra_nodes)
                continue
            sel.notes.insert(0, f"{fell_back}: fell back to the {mode} grid")
            yield sel
    except deadline.TimeUp as exc:  # (what the graded grid met says most)
        exc.add_note(f"{fell_back}, and the {grid} grid found none in time")
        raise
    if too_many is not None:
        raise LimitError(
            f"{contour.source}: {fell_back}, and the {too_many[0]} grid's path needs "
            f"{too_many[1]:,} extra boundary nodes for {contour.n} points (over "
            f"{MAX_FALLBACK_EXTRA} a point); re-space the contour (--resample), or give "
            "--grid uniform to mesh it so"
        )


def _ungraded(contour: Contour, o: MeshOptions, mode: str) -> Iterator[Selection]:
    """The adapted rungs (``mode == "adapt"``) and Appendix A's uniform grid."""
    if mode == "adapt":
        yield from _respace.candidate_selections(
            contour, o.h, o.box, o.margin, o.strict, o.max_nodes, o.exterior
        )
    sel = select(
        contour,
        h=o.h,
        box=o.box,
        margin=o.margin,
        strict=o.strict,
        max_nodes=o.max_nodes,
        exterior=o.exterior,
    )
    if mode == "adapt":
        sel.notes.insert(
            0,
            "the adapted grid did not work here (no simple path, a fold, or "
            "an angle under 1 degree on every rung): "
            "fell back to the uniform grid",
        )
    yield sel


def run_select(contour: Contour, options: MeshOptions | None = None, **changes) -> Selection:
    """Stage 1: the first of :func:`candidate_selections` (the options' select fields),
    searched for at most :func:`.deadline.search_bound` seconds."""
    try:
        with deadline.limit(deadline.search_bound(contour.n)):
            return next(candidate_selections(contour, options, **changes))
    except deadline.TimeUp as exc:
        raise LimitError(_time_up(contour, exc)) from None


def _time_up(contour: Contour, exc: deadline.TimeUp) -> str:
    """The refusal of a contour whose search for a grid path ran out of time."""
    why = "".join(f"; {note}" for note in getattr(exc, "__notes__", ()))
    return (
        f"{contour.source}: {exc} ({contour.n} points){why}; simplify the contour or "
        "re-space it (--resample)"
    )


#: The narrow band reaches this many cells (grid steps, in i or j) past the
#: nearest path node, and at least :data:`BAND_REACH` times the largest distance a
#: path node travels.  With the quality stage a band of 4 cells gives the same
#: smallest angles as the whole grid (tests/test_band.py allows 0.05 degrees) at
#: about half the cost of 8 (``benchmarks/MEASURED.md``).
BAND_CELLS = 4
BAND_REACH = 3.0


def band_nodes(sel: Selection) -> np.ndarray | None:
    """Boolean node mask of the narrow band, or None when it would not save much."""
    if isinstance(sel, GradedSelection):
        return sel.band_nodes()
    g = sel.grid
    h = min(g.hx, g.hy)
    travel = np.hypot(*(sel.path_targets - g.coords(sel.path_nodes)).T).max(initial=0.0)
    if sel.path_slide is not None:
        travel = max(travel, float(np.abs(sel.path_slide[:, 1] - sel.path_slide[:, 0]).max()))
    reach = max(BAND_CELLS, int(np.ceil(BAND_REACH * travel / h)))
    on = np.zeros((g.ny + 1, g.nx + 1), dtype=bool)
    i, j = g.node_ij(sel.path_nodes)
    on[j, i] = True
    band = _dilate(_dilate(on, reach, 0), reach, 1).ravel()
    return band if band.sum() < 0.5 * g.n_nodes else None


def _dilate(on: np.ndarray, reach: int, axis: int) -> np.ndarray:
    """True where ``on`` has a True within ``reach`` places along ``axis``.

    (``scipy.ndimage.maximum_filter`` does this too, but its import is slow.)
    """
    c = np.cumsum(on, axis=axis, dtype=np.int64)
    c = np.concatenate([np.zeros_like(c.take([0], axis=axis)), c], axis=axis)
    n = on.shape[axis]
    hi = np.minimum(np.arange(n) + reach + 1, n)
    lo = np.maximum(np.arange(n) - reach, 0)
    return c.take(hi, axis=axis) > c.take(lo, axis=axis)


def run_deform(
    contour: Contour,
    sel: Selection,
    options: MeshOptions | None = None,
    *,
    callback: Callback | None = None,
    size_function: SizeFunction | None = None,
    keep_folds: bool = False,
    **changes,
) -> Deformed:
    """Stage 2 (the options' deform fields).  The size function (``size_function``, else
    the one the options' ``size`` or ``size_field`` give; normalised here over the
    grid's box) shapes the cells.

    ``solve="band"`` moves only the cells near the path (:func:`band_nodes`),
    unless a size function is given (it shapes every cell) or the band would
    cover half the grid; ``"full"`` solves on the whole grid.  On the graded grid
    without a size function only the domain's side of the path is solved for
    (:func:`.deform.deform_band`'s ``kept``): the other side's triangles are dropped,
    and a fold there does not stop the deformation.

    ``keep_folds``: a fold that cannot be avoided does not stop the deformation
    (:func:`.deform.deform_`);
    the stats' ``fold`` then says where it first folded, and stage 3 mends the mesh
    (:mod:`.untangle`).  A deformation that cannot go on at all still raises
    :class:`FoldError`.
    """
    o = _options(options, changes)
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
    band = band_nodes(sel) if o.solve == "band" and size is None else None
    kwargs = {
        "steps": o.steps,
        "callback": callback,
        "describe": _describer(contour, sel),
        "solver": o.solver,
        "size": None if size is None else _size.SizePath(size.g1, grid.box),
        "slide": None
        if sel.path_slide is None
        else _respace.Slide(
            contour, sel.path_ring, sel.path_slide[:, 0], sel.path_slide[:, 1], sel.path_targets
        ),
        "keep_folds": keep_folds,
    }
    args = (pts0, tri, sel.path_nodes, sel.path_targets, grid.boundary_nodes())
    kept = None  # (the uniform grid deforms both sides, as the paper does)
    if isinstance(sel, GradedSelection) and size is None:
        kept = sel.kept_triangles()
        kwargs["flat_ok"] = True  # (stage 3 meshes flat triangles again)
    try:
        try:
            if kept is not None:
                pos, st = _deform.deform_band(*args, band, kept=kept, **kwargs)
            elif band is None:
                pos, st = _deform.deform(*args, **kwargs)
            else:
                pos, st = _deform.deform_band(*args, band, **kwargs)
        except FoldError:
            if size is None or not isinstance(sel, GradedSelection):
                raise
            pos, st = _fit_then_size(args, kwargs, size, sel)
    except SolverError as exc:
        if keep_folds:  # (a triangle squeezed flat on the way: nothing to mend)
            raise FoldError(f"{contour.source}: the deformation folded and failed: {exc}") from None
        raise SolverError(f"{contour.source}: deformation failed: {exc}") from None
    if st.fold is not None and not np.isfinite(pos).all():
        raise FoldError(st.fold)
    return Deformed(sel, pos, st)


def _fit_then_size(args: tuple, kwargs: dict, size: SizeFunction, sel: GradedSelection):
    """The graded grid's deformation in two parts, where one with ``size`` folds:
    first onto the contour without it, then, the path nodes held, from the grid's
    own density (:func:`.size.grid_density`) to ``size``'s, kept within
    :data:`.size.MAX_DENSITY_RATIO` of it (:func:`.size.limited_target`).

    One part folds where ``f`` asks by the contour for cells smaller than its points
    allow, or where the graded grid's density varies so much that the contour's
    displacement, scaled by it, runs away from the contour.  Returns the positions
    and the two parts' statistics summed."""
    _, tri, path_nodes, _, fixed = args
    pos, fit = _deform.deform(*args, **{**kwargs, "size": None})
    box = sel.grid.box
    g0 = _size.grid_density(pos, tri, box)
    path = _size.SizePath(_size.limited_target(size.g1, g0, box), box, g0=g0)
    held = pos[path_nodes]
    pos, st = _deform.deform(
        pos, tri, path_nodes, held, fixed, **{**kwargs, "size": path, "slide": None}
    )
    st.solves += fit.solves
    st.halvings += fit.halvings
    st.iterations = fit.iterations + st.iterations
    return pos, st


def _describer(contour: Contour, sel: Selection):
    src = sel.path_source
    nodes = sel.path_nodes

    def describe(tri_nodes) -> str:
        hit = np.flatnonzero(np.isin(nodes, tri_nodes) & (src >= 0))
        if len(hit) == 0:
            return ""
        return f" (by contour {contour.where(int(src[hit[0]]))})"

    return describe


def run_triangulate(
    contour: Contour,
    d: Deformed,
    options: MeshOptions | None = None,
    *,
    size_function: SizeFunction | None = None,
    cut: triangulate.Cut | None = None,
    fill: bool = True,
    **changes,
) -> tuple[Mesh, dict]:
    """Stage 3: the mesh and its summary.  ``cut``: :func:`.triangulate.cut` of this
    selection, if already made.  The options' ``improve`` runs the quality stage
    (:mod:`.improve`); their size function (or ``size_function``) is reported on.
    ``fill=False``: of :data:`MERGE_WAYS`, only the ways without new points.  The
    summary's ``merge_ways`` lists the ways measured against the bound."""
    o = _options(options, changes)
    size = size_function
    if size is None:
        size = _size.make(o.size, o.size_field, contour)
    sel = d.selection
    if cut is None:
        cut = triangulate.cut(contour, sel)
    graded = isinstance(sel, GradedSelection)
    placed = triangulate.place(contour, sel, cut, d.points, folded=graded)
    edges = cut.edges
    if graded:  # folded triangles (a deformation that kept them) or flat ones: mended
        mended = untangle.untangle(placed, untangle.most_tangled(placed))
        if mended is None:
            raise FoldError(
                (d.stats.fold if d.stats is not None else None)
                or f"{contour.source}: the deformed grid has folded or flat triangles that "
                "could not be meshed again"
            )
        if mended is not placed:
            sel.notes.append("folded or flat triangles of the deformed grid were meshed again")
            placed, edges = mended, None  # (the contract check counts the new triangles' edges)
    # merged down to 1 degree (a graded path's extra nodes) or 20, cavities filled with
    # new points where that is not enough; if the quality stage then leaves triangles
    # under its bound, the next way that leaves fewer (``MERGE_WAYS``)
    ways = MERGE_WAYS[isinstance(sel, GradedSelection)]
    if not o.improve:  # (filling counts on the quality stage, and on the check after it)
        ways = ways[-1:]
    elif not fill:
        ways = tuple(w for w in ways if not w[1])
    best = None
    unfilled = set()  # the ``thin`` of each way that filled no cavity (no fill: same mesh)
    measured = []  # each way measured against the bound
    for thin, fills in ways:
        if not fills and thin in unfilled:
            continue  # (it would give the mesh already measured)
        got = _merge_and_improve(placed, edges, o, thin, fills)
        merged = got[2]
        if merged is None or not o.improve:
            best = got  # (nothing merged, or one way only)
            break
        if fills and not merged.filled:
            unfilled.add(thin)
        under = forced.under_bound(got[0].points, got[0].triangles, got[0].lines)
        measured.append(
            {
                "thin": thin,
                "fill": fills,
                "extra_boundary_nodes": int(got[0].n_extra),
                "under_bound": int(under),
            }
        )
        if best is None or (under, got[0].n_extra) < (best[4], best[0].n_extra):
            best = (*got, under)
        if under == 0 or not (thin or merged.filled):
            break  # (the bound kept, or nothing thin in this way: the next are alike)
    mesh, edges, merged, better = best[:4]
    # the contract check and the summary read the mesh independently; numpy and
    # scipy release the GIL in their loops, so on two cores the pair takes about as
    # long as the longer one (``benchmarks/MEASURED.md``)
    with ThreadPoolExecutor(max_workers=2) as pool:
        summary = pool.submit(quality.stats, mesh)
        quality.check_contract(mesh, contour, sel.grid.box if sel.exterior else None, edges)
        report = summary.result()
    report["contract"] = "ok"
    report["merged_extra_nodes"] = 0 if merged is None else merged.merged
    report["merge_ways"] = measured
    report["improve"] = (
        None
        if better is None
        else {
            "min_angle_before": better.min_angle_before,
            "flips": better.flips,
            "node_moves": better.moves,
            "nodes_added": better.added,
            "corner_nodes_removed": better.corners,
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
    return mesh, report


#: How stage 3 merges extra nodes, in turn, while the quality stage leaves triangles
#: under its bound: ``(thin, fill)`` for :func:`.merge.merge_extra_nodes`, on a
#: graded path's extra nodes (True) and on the other grids' (False).  Of the ways
#: tried, the mesh with the fewest triangles under the bound is kept, then the one
#: with the fewest extra nodes left.  On the other grids the thin way without new
#: points comes second: a thin bar with a few far-apart points (an X of 20) has no
#: fill of new points that keeps the bound, and no 20-degree triangulation of its
#: cavities, but one down to 1 degree that keeps it.  On a graded path a 20-degree
#: fill second never left fewer triangles under the bound than the first way, on
#: the corpus nor on 300 random star polygons, and cost up to 1 s
#: (``benchmarks/MEASURED.md``).
MERGE_WAYS = {
    True: ((True, True), (True, False)),
    False: ((False, True), (True, False), (False, False)),
}


def _merge_and_improve(mesh: Mesh, edges, o: MeshOptions, thin: bool, fill: bool):
    """Stage 3 after placing: extra nodes merged (:mod:`.merge`; ``thin``: a graded
    path's), then the quality stage; ``(mesh, edges for the contract check or None,
    Merged or None, ImproveStats or None)``."""
    merged = None
    if mesh.n_extra and _merges(o):
        mesh, merged = _merge.merge_extra_nodes(mesh, thin=thin, fill=fill)
        if merged.merged:
            edges = None  # (the contract check counts the new triangles' edges)
    better = None
    if o.improve:
        before = mesh
        mesh, better = _improve.improve(mesh, clear_corners=not _paper_form(o))
        if better.corners:  # nodes taken out: the contract check counts afresh
            edges = None
        elif len(better.changed) and edges is not None:  # the changed triangles' edges
            old = len(before.triangles)
            edges = geometry.patch_edge_uses(
                edges,
                mesh.n_nodes,
                before.triangles[better.changed],
                np.concatenate([mesh.triangles[better.changed], mesh.triangles[old:]]),
            )
    return mesh, edges, merged, better


def _merges(o: MeshOptions) -> bool:
    """Whether stage 3 merges extra boundary nodes (``merge_extra``; ``auto``: not on
    the uniform grid, the paper's form)."""
    if o.merge_extra != "auto":
        return o.merge_extra == "merge"
    return not _paper_form(o)


def _paper_form(o: MeshOptions) -> bool:
    """Appendix A's uniform grid asked for (``--grid uniform`` or ``--h``): its meshes
    stay as the paper builds them (no merging, no clearing of sharp corners)."""
    return o.grid == "uniform" or o.h is not None


#: An adapted-grid mesh whose smallest angle is below this (degrees) gives way to the
#: next rung of the ladder, and is kept only if no later rung meshes (measured: an
#: icon slid at h had a triangle of 3e-10 degrees).
MIN_ADAPTED_ANGLE = 1.0


def mesh_contour(
    contour: Contour,
    options: MeshOptions | None = None,
    *,
    callback: Callback | None = None,
    size_function: SizeFunction | None = None,
    **changes,
) -> MeshResult:
    """Mesh the inside of ``contour`` (or the box minus it, ``exterior``).

    ``options`` (default: :class:`~.options.MeshOptions`' defaults) with
    ``changes`` (its field names: ``mesh_contour(c, exterior=True)``);
    ``callback(done, stats)`` follows the deformation; ``size_function`` replaces
    the options' ``size`` and ``size_field``.  With ``max_h``, the contour's edges
    longer than it are split first (:func:`split`), and the mesh numbers the given
    points first (:func:`given_first`).
    """
    o = _options(options, changes)
    fine, given = split(contour, o)
    res = _mesh_contour(fine, o, callback=callback, size_function=size_function)
    if given is None:
        return res
    sel = res.selection
    box = sel.grid.box if sel.exterior else None
    mesh, report = given_first(res.mesh, res.report, contour, fine, given, box)
    return MeshResult(mesh, sel, res.deform_stats, report)


@dataclass
class Constructed:
    """:func:`mesh_constructed`'s result: the mesh, the selection on the grid contour,
    the ears cut, and each stage's seconds (for the benchmark; nothing reads them)."""

    mesh: Mesh
    selection: GradedSelection
    ears: np.ndarray
    seconds: dict = field(default_factory=dict)


def mesh_constructed(
    contour: Contour,
    options: MeshOptions | None = None,
    *,
    seconds: dict | None = None,
    **changes,
) -> Constructed:
    """The constructed graded selection's stages chained (not yet what
    :func:`mesh_contour` runs): sharp ears cut (:func:`.construct.cut_ears`), the
    grid contour selected, deformed keeping folds, folds meshed again, the boundary
    recovered (:mod:`.recover`), the ears added back, the quality stage, the contract
    checked.  Options read: ``exterior``, ``growth``, the deformation's.
    ``seconds``: filled with each stage's time as it ends (also when a later one
    raises)."""
    o = _options(options, changes)
    seconds = {} if seconds is None else seconds
    start = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal start
        now = time.perf_counter()
        seconds[stage], start = now - start, now

    grid_contour, kept, ears = _construct.cut_ears(contour, o.exterior)
    sel = _construct.select_constructed(grid_contour, exterior=o.exterior, growth=o.growth)
    lap("select")
    d = run_deform(grid_contour, sel, o, keep_folds=True)
    lap("deform")
    cut = triangulate.cut(grid_contour, sel)
    placed = triangulate.place(grid_contour, sel, cut, d.points, folded=True)
    mended = untangle.untangle(placed, untangle.most_tangled(placed))
    if mended is None:
        raise FoldError(f"{contour.source}: the deformed grid has folds that could not be mended")
    lap("mend")
    mesh, _ = _recover.recover(mended)
    mesh = _construct.restore_ears(mesh, contour, kept, ears, o.exterior)
    lap("recover")
    mesh, _ = _improve.improve(mesh)
    lap("improve")
    quality.check_contract(mesh, contour, sel.grid.box if o.exterior else None)
    return Constructed(mesh, sel, ears, seconds)


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


def split(contour: Contour, o: MeshOptions) -> tuple[Contour, np.ndarray | None]:
    """The contour the grid is laid for, and where its given points are in it:
    :func:`.contour.split_edges` at ``--max-h``."""
    return split_edges(contour, o.max_h, o.max_nodes)


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


def _mesh_contour(
    contour: Contour,
    o: MeshOptions,
    *,
    callback: Callback | None = None,
    size_function: SizeFunction | None = None,
) -> MeshResult:
    """:func:`mesh_contour` on the contour as the grid is laid for it.

    On an adapted grid, a rung whose deformation folds, or whose mesh has an
    angle under :data:`MIN_ADAPTED_ANGLE`, gives way to the next one (the
    nearly flat mesh is kept if nothing later meshes).  A graded selection whose
    deformation folds is deformed again keeping its folds, and its mesh mended
    (:mod:`.untangle`), if no graded mesh was good enough to skip the fallback
    grid.  Once stage 3's ways with new points have done worse than one without
    (:func:`_fill_lost`), the later meshes skip them.  The result meets the
    contract or this raises.
    """
    size = size_function
    if size is None:
        size = _size.make(o.size, o.size_field, contour)
    fold = flat = best = None
    enough = EXTRA_ENOUGH * len(contour.points)
    folded: list[GradedSelection] = []  # graded selections whose deformation folded
    fill = True  # stage 3 tries the ways with new points (until they lose: ``_fill_lost``)

    def rank(mesh: Mesh, report: dict) -> tuple:
        """Meshes that keep the quality stage's bound first, then fewer extra nodes,
        then the larger smallest angle."""
        ways = report["merge_ways"]  # (the mesh kept is the way with the fewest under)
        if ways:
            under = min(w["under_bound"] for w in ways)
        else:
            under = forced.under_bound(mesh.points, mesh.triangles, mesh.lines)
        return (under > 0, report["extra_boundary_nodes"], -report["min_angle"])

    def fall_back() -> bool:  # not for a few extra nodes left: not worth its time
        return best is None or best[0] > (False, enough)

    with deadline.limit(deadline.search_bound(contour.n)):
        try:
            for sel in candidate_selections(
                contour, o, size_function=size, fall_back=fall_back, mend=folded
            ):
                with_extra = isinstance(sel, GradedSelection) and sel.extra_nodes > 0
                mending = any(sel is s for s in folded)  # (yielded again, to be mended)
                # stage 3's topology (which triangles, numbered how, and their edges) needs
                # only the selection: it runs on the second core while the deformation runs
                # (``benchmarks/MEASURED.md``)
                sel.triangles()  # built once, here, rather than by both threads at once
                if isinstance(sel, GradedSelection):
                    sel.kept_triangles()
                with ThreadPoolExecutor(max_workers=1) as pool:
                    cut = pool.submit(triangulate.cut, contour, sel, edges=True)
                    try:
                        d = run_deform(
                            contour,
                            sel,
                            o,
                            callback=callback,
                            size_function=size,
                            keep_folds=mending,
                        )
                    except FoldError as exc:
                        fold = exc  # the last one: the uniform grid's, when every rung folded
                        if isinstance(sel, GradedSelection) and not mending:
                            folded.append(sel)
                        continue
                    try:
                        mesh, report = run_triangulate(
                            contour, d, o, size_function=size, cut=cut.result(), fill=fill
                        )
                    except (ContractError, FoldError) as exc:
                        if not isinstance(sel, GradedSelection):
                            raise
                        # a triangle left flat (its sign, and whether its centroid lies in
                        # the domain, round-off; to be mended later), or folds that could
                        # not be mended: the next
                        fold = exc
                        if isinstance(exc, ContractError) and not mending:
                            folded.append(sel)
                        continue
                fill = fill and not _fill_lost(report["merge_ways"])
                if with_extra:
                    # the graded mesh that keeps the bound with the fewest extra nodes left
                    # after merging; the next ways, then the fallback grid, may do better
                    got = (rank(mesh, report), sel, d, mesh, report)
                    if best is None or got[0] < best[0]:
                        best = got
                    if best[0][:2] == (False, 0) and not _tries_every_way(contour):
                        break  # (a small contour tries its other ways too, for a better angle)
                    continue
                if sel.h_rule != _respace.ADAPTED or report["min_angle"] >= MIN_ADAPTED_ANGLE:
                    break
                flat = flat or (sel, d, mesh, report)  # nearly flat: try the next rung first
            else:
                if best is None and flat is None:
                    raise fold
                sel, d, mesh, report = best[1:] if best is not None else flat
        except deadline.TimeUp as exc:
            # (refused even with a mesh in hand: which mesh the search had reached by
            # then would depend on the machine's load, and a mesh never does)
            raise LimitError(_time_up(contour, exc)) from None
        except (SelectionError, LimitError):  # (the uniform grid's)
            if best is None and flat is None:
                raise
            sel, d, mesh, report = best[1:] if best is not None else flat
    if best is not None and best[1] is not sel and best[0] <= rank(mesh, report):
        sel, d, mesh, report = best[1:]  # (as good or better, on fewer nodes)
    report.update(selection_report(sel))
    if d.stats is not None:
        report["moved_nodes"] = int(d.stats.moved_nodes)  # the band's nodes, or every node
    return MeshResult(mesh, sel, d.stats, report)


def _fill_lost(ways: list[dict]) -> bool:
    """Whether, of stage 3's ways measured (a summary's ``merge_ways``), one without new
    points left fewer triangles under the bound than every one with them.

    Then the contour's later meshes skip the ways with new points: where the points
    are few along thin parts, filled cavities there are slivers on any grid.  On an
    icon with long edges down bars one cell wide the graded grid's fill
    left 88 triangles under the bound, the way without new points 2, and the adapted
    grid's fill 165, a second of a 3 s run; it changes no mesh of the corpus, the
    samples or 640 random polygons (``benchmarks/MEASURED.md``)."""
    filled = [w["under_bound"] for w in ways if w["fill"]]
    unfilled = [w["under_bound"] for w in ways if not w["fill"]]
    return bool(filled and unfilled) and min(unfilled) < min(filled)


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
