"""Moving boundaries: one connectivity for every frame, never tangled.

The paper's section 3.2: a mesh on a moving domain is carried along by the
deformation.  Frame ``k``'s mesh is frame ``k - 1``'s deformed by the
div-curl scheme of stage 2 over pseudo-time (:func:`.deform.deform`): the
contour nodes go to frame ``k``'s points (Dirichlet), the extra boundary
nodes stay at the same place along their contour edge, the box nodes of an
exterior mesh stay put (``U = 0``), and every pseudo-time step is checked
for folds and refined (halved) if one would fold.  The triangles never
change: the same index arrays in every frame.  After each frame the mesh
contract is checked against that frame's contour.

Before the solve, each ring's best rigid motion is carried into the mesh by a
smooth weight (:func:`carry`): a turning body needs a twist, which the
div-curl system with ``curl U = 0`` cannot give.

Data flow::

    mesh file (points, triangles) + first frame (how many points, which rings)
      --prepare--> Motion (the Mesh with its boundary, who moves, who is held,
                   each ring's weight)
    Motion, points of frame k-1, contour of frame k
      --advance--> rigid part (carry), rest (div-curl) --> points of frame k
                   (or FoldError), contract checked
    mesh file + frame files --move_frames--> one mesh file per frame (+ .pvd)

Nothing here prints or exits.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from . import files, formats, geometry, quality
from .contour import Contour, make_contour
from .deform import ADVICE, DEFAULT_STEPS, DeformStats, deform, deform_band
from .errors import (
    BandError,
    ContractError,
    DegradedError,
    FoldError,
    InputError,
    OptionError,
    printable,
)
from .mesh import Mesh, as_triangles, guarded
from .options import MoveOptions
from .readers import load_contour


@dataclass
class Motion:
    """A mesh ready to follow its contour: who moves and who is held."""

    mesh: Mesh  # frame 0, with its boundary lines and groups
    contour: Contour  # frame 0's contour: the mesh's own contour nodes
    box: tuple | None  # the box of an exterior mesh (held), else None
    moving: np.ndarray  # contour nodes 0..m-1, then the extra boundary nodes
    held: np.ndarray  # box nodes
    extra_from: np.ndarray  # per extra boundary node: the contour point before it,
    extra_to: np.ndarray  # the one after it,
    extra_at: np.ndarray  # and how far along that edge it sits (0..1)
    rings: list[np.ndarray]  # per ring: positions in ``moving`` of its nodes
    weights: list[np.ndarray]  # per ring, per node: how much of its rigid motion it follows
    edges: tuple | None  # geometry.edge_uses of the triangles (none with quads)
    #: the triangles the deformation keeps unfolded: the mesh's, and each quad's four
    #: corner triangles (both diagonals' halves: all positive, the quad stays convex)
    guard: np.ndarray | None = None

    @property
    def cells(self) -> np.ndarray:
        return self.mesh.triangles if self.guard is None else self.guard


@dataclass
class Step:
    """One frame reached: its points, the deformation's statistics, its summary."""

    points: np.ndarray
    stats: DeformStats
    report: dict


def prepare(points: np.ndarray, tri: np.ndarray, first: Contour, source: str, quads=None) -> Motion:
    """The mesh read from ``source`` as a :class:`Motion`, given its first frame
    (``quads``: its quads, if any).

    The mesh must be one deformesh wrote for a contour of as many points as
    ``first``, ring by ring the same: its nodes ``0 .. m-1`` are the contour
    points in order (the contract), and they must bound the mesh as they did
    for its contour.  Raises :class:`DeformeshError` naming ``source`` if not.
    """
    m = first.n
    if len(points) < m:
        raise InputError(
            f"{source}: the mesh has {len(points)} nodes, fewer than the "
            f"{m} points of {first.source}"
        )
    try:
        own = make_contour(
            points[:m],
            source=source,
            ring_starts=first.starts[:-1],
            ring_labels=first.ring_labels or None,
        )
    except InputError as exc:
        raise InputError(
            f"{source}: its first {m} nodes are not a valid contour like "
            f"{first.source}'s ({exc}); was it written by deformesh from "
            f"{m} points?"
        ) from None
    quads = np.zeros((0, 4), dtype=np.int64) if quads is None else quads
    edges = geometry.edge_uses(as_triangles(tri, quads), len(points))
    ring = first.starts[1] - first.starts[0]
    held = _first_ring(edges)
    if held is not None and held != ring:  # (the mesh's own first ring: the frame differs)
        what = "" if first.n_rings == 1 else " on its first ring"
        raise InputError(
            f"{first.source}: has {ring} points{what}, but {source}'s contour has {held}"
            f"{what} (point k of each frame follows contour point k)"
        )
    try:
        mesh, box = quality.mesh_for_contour(points, tri, own, quads)
        quality.check_contract(mesh, own, box, edges)
    except ContractError as exc:
        raise InputError(
            f"{source}: not a deformesh mesh of {m} contour points in order "
            f"({str(exc).removeprefix(source + ': ')})"
        ) from None
    _same_rings(own, first, first.source)
    # each extra boundary node's contour edge (the contour nodes before and after it
    # on its ring) and how far along it sits
    on_rings = mesh.line_group < own.n_rings
    none = np.zeros(0, np.int64)
    nodes, ring_of, ext_from, ext_to, ext_at = [none], [own.ring], [none], [none], [np.zeros(0)]
    for r in range(own.n_rings):
        chain = mesh.lines[mesh.line_group == r, 0]
        is_point = chain < m
        if is_point.all():
            continue
        pos, idx = np.flatnonzero(is_point), np.flatnonzero(~is_point)
        k = np.searchsorted(pos, idx)
        before, after = chain[pos[k - 1]], chain[pos[k % len(pos)]]
        a, b, x = points[before], points[after], points[chain[idx]]
        ab = b - a
        nodes.append(chain[idx])
        ring_of.append(np.full(len(idx), r))
        ext_from.append(before)
        ext_to.append(after)
        ext_at.append(((x - a) * ab).sum(axis=1) / (ab * ab).sum(axis=1))
    extra = np.concatenate(nodes)
    held = np.unique(mesh.lines[~on_rings].ravel())  # the box
    moving = np.concatenate([np.arange(m), extra])
    # each ring's nodes (its points, then its extra nodes), as positions in ``moving``
    ring_of = np.concatenate(ring_of)
    rings = [np.flatnonzero(ring_of == r) for r in range(own.n_rings)]
    weights = [
        rigid_weight(
            points, moving[r], np.concatenate([moving[np.flatnonzero(ring_of != k)], held])
        )
        for k, r in enumerate(rings)
    ]
    return Motion(
        mesh,
        own,
        box,
        moving,
        held,
        np.concatenate(ext_from),
        np.concatenate(ext_to),
        np.concatenate(ext_at),
        rings,
        weights,
        None if len(quads) else edges,
        guarded(tri, quads) if len(quads) else None,
    )


def rigid_weight(points: np.ndarray, own: np.ndarray, others: np.ndarray) -> np.ndarray:
    """1 at the nodes ``own`` (a ring), 0 at ``others`` (the other rings and the box),
    smooth between: ``1 - s(u)``, ``u`` the distance to the nearest own node over that
    plus the distance to the nearest other one, ``s(u) = 3u^2 - 2u^3``.  All 1 when
    there is no other (an interior mesh of one ring: the whole mesh follows its
    rigid motion)."""
    if len(others) == 0:
        return np.ones(len(points))
    from scipy.spatial import cKDTree

    d_own = cKDTree(points[own]).query(points)[0]
    d_other = cKDTree(points[others]).query(points)[0]
    u = d_own / np.maximum(d_own + d_other, np.finfo(float).tiny)
    return 1.0 - u * u * (3.0 - 2.0 * u)


def rigid_fit(p: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The rigid motion closest to taking points ``p`` to ``q`` (least squares):
    ``q ~ cq + R(theta) (p - cp)``, ``cp`` and ``cq`` the centroids.  Returns (cp, cq,
    theta)."""
    cp, cq = p.mean(axis=0), q.mean(axis=0)
    a, b = p - cp, q - cq
    theta = np.arctan2((a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum(), (a * b).sum())
    return cp, cq, float(theta)


def carry(
    points: np.ndarray, weight: np.ndarray, cp: np.ndarray, cq: np.ndarray, theta: float
) -> np.ndarray:
    """Each node turned by ``weight * theta`` about ``cp`` and shifted by ``weight`` of
    ``cq - cp``: the rigid motion where the weight is 1, nothing where it is 0."""
    out = np.array(points, dtype=np.float64, copy=True)
    on = weight > 0  # the others stay exactly where they are (the box: to the bit)
    w = weight[on]
    c, s = np.cos(w * theta), np.sin(w * theta)
    d = points[on] - cp
    out[on] = (
        cp
        + np.column_stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]])
        + w[:, None] * (cq - cp)
    )
    return out


def _first_ring(edges) -> int | None:
    """How many nodes the mesh's first contour ring has, read off its boundary: the
    nodes ``0, 1, .., L - 1`` joined in turn by boundary edges (one triangle each),
    ``L - 1`` back to 0; None where they are not (extra boundary nodes on a contour
    edge, or not a deformesh mesh)."""
    lo, hi, fwd, rev = edges
    once = (fwd + rev) == 1
    step = np.zeros(int(lo.max(initial=0)) + 2, dtype=bool)
    chain = once & (hi == lo + 1)
    step[lo[chain]] = True  # node i joined to i + 1 by a boundary edge
    length = int(np.argmin(step)) + 1  # (the first i without: the run ends at node i)
    closes = once & (lo == 0) & (hi == length - 1)
    return length if length >= 3 and closes.any() else None


def _same_rings(own: Contour, frame: Contour, source: str) -> None:
    """A frame must have the mesh's rings: as many points each, the same way round,
    holes where holes were."""
    if frame.n != own.n:
        raise InputError(
            f"{source}: has {frame.n} points, the mesh's contour has "
            f"{own.n} (point k of each frame follows contour point k)"
        )
    if frame.starts != own.starts:
        raise InputError(
            f"{source}: its rings start at points {list(frame.starts[:-1])}, "
            f"the mesh's at {list(own.starts[:-1])}"
        )
    for r in range(own.n_rings):
        if frame.ring_clockwise[r] != own.ring_clockwise[r]:
            raise InputError(
                f"{source}: {frame.ring_labels[r]} runs the other way round "
                "from the mesh's (a frame cannot turn a ring inside out)"
            )
        if frame.is_hole(r) != own.is_hole(r):
            raise InputError(
                f"{source}: {frame.ring_labels[r]} is "
                f"{'a hole' if frame.is_hole(r) else 'not a hole'}, "
                "unlike in the mesh"
            )


def check_frame(motion: Motion, frame: Contour) -> None:
    """Raise :class:`DeformeshError` naming the frame's file if it cannot follow the mesh's
    contour point by point."""
    _same_rings(motion.contour, frame, frame.source)


def targets(motion: Motion, frame: Contour) -> np.ndarray:
    """Where the moving nodes go for ``frame``: its points, then each extra boundary node
    as far along its contour edge as it was."""
    p = frame.points
    t = motion.extra_at[:, None]
    extra = (1 - t) * p[motion.extra_from] + t * p[motion.extra_to]
    return np.concatenate([p, extra])


def advance(
    motion: Motion,
    points: np.ndarray,
    frame: Contour,
    steps: int = DEFAULT_STEPS,
    solver: str = "auto",
    solve: str = "full",
    describe: Callable[[np.ndarray], str] | None = None,
    advice: tuple[str, str] = ADVICE,
) -> Step:
    """Deform ``points`` (the previous frame's) so the contour nodes sit on ``frame``.

    Raises :class:`.errors.FoldError` when no refinement of the pseudo-time steps
    avoids a fold, :class:`.errors.ContractError` if the result breaks the contract.
    """
    goal = targets(motion, frame)
    start = points
    # each ring's rigid motion first, carried by its weight (the twist a turning
    # body needs, which curl U = 0 cannot give); a fraction of it if all would fold
    fits = [rigid_fit(points[motion.moving[r]], goal[r]) for r in motion.rings]
    share = 1.0
    while share > 1.0 / 64:
        start = points
        for w, (cp, cq, theta) in zip(motion.weights, fits):
            if theta != 0 or (cq != cp).any():  # (a ring at rest: not a bit moves)
                start = carry(start, w, cp, cp + share * (cq - cp), share * theta)
        if (geometry.signed_areas(start, motion.cells) > 0).all():
            break
        share /= 2
    else:
        start, share = points, 0.0
    kwargs = {"steps": steps, "solver": solver, "describe": describe, "advice": advice}
    # then the rest by the div-curl scheme, on the whole mesh; or (``solve="band"``, an
    # exterior mesh) on a band around the moving nodes, the rest held as the box is, and
    # on the whole mesh if the band is too narrow.  (An interior mesh always whole: a
    # band there holds the middle while the contour moves; a pulsating peanut fell to
    # 1.7 degrees, 31.0 on the whole mesh.)  Nothing to solve when the rigid motion
    # took the contour nodes there already (within :data:`AT_TARGET` of the contour's
    # size: frames written with 10 digits): the div-curl system with zero data has the
    # zero solution.
    new = None
    rest = float(np.max(np.abs(goal - start[motion.moving]), initial=0.0))
    if rest <= AT_TARGET * float(np.abs(goal).max() + np.ptp(goal)):
        new = start.copy()
        new[motion.moving] = goal
        stats = DeformStats(steps=0, solver="none", moved_nodes=0)
        if not (geometry.signed_areas(new, motion.cells) > 0).all():
            new = None  # (the last nudge folds: leave it to the solve)
    if new is None and solve == "band" and len(motion.held):
        band = _band(start, motion, goal)
        if band is not None:
            try:
                new, stats = deform_band(
                    start, motion.cells, motion.moving, goal, motion.held, band, **kwargs
                )
            except (FoldError, BandError):  # folds in the band, or a moving node on its edge
                new = None
    if new is None:
        new, stats = deform(start, motion.cells, motion.moving, goal, motion.held, **kwargs)
    out = frame_mesh(motion, new)
    quality.check_contract(out, frame, motion.box, motion.edges)
    report = quality.stats(out)
    report.update(
        solves=stats.solves,
        halvings=stats.halvings,
        rigid_turn=[float(np.degrees(share * f[2])) for f in fits],
        rigid_share=share,
        max_displacement=float(np.max(np.hypot(*(new - points).T))),
    )
    return Step(new, stats, report)


#: Contour nodes this close to their targets after the rigid motion (relative to the
#: contour's size) are put there without a solve.
AT_TARGET = 1e-9

#: The band of the div-curl solve reaches this many mean boundary edge lengths from the
#: moving nodes, or this many times their farthest travel if that is more.
BAND_EDGES = 4
BAND_TRAVEL = 3


def _band(points: np.ndarray, motion: Motion, goal: np.ndarray) -> np.ndarray | None:
    """Nodes within reach of the moving ones (a mask), or None if that is every node."""
    from scipy.spatial import cKDTree

    lines = motion.mesh.lines
    edge = float(np.mean(np.hypot(*(points[lines[:, 1]] - points[lines[:, 0]]).T)))
    # the farthest travel of a moving node: in this frame, or since frame 0 but for the
    # rigid motion (a band sized by one frame's steps alone lets the changes of shape
    # pile up at its edge, frame after frame)
    origin = motion.mesh.points[motion.moving]
    cp, cq, theta = rigid_fit(origin, goal)
    since = carry(origin, np.ones(len(origin)), cp, cq, theta) - goal
    travel = max(
        float(np.max(np.hypot(*(goal - points[motion.moving]).T), initial=0.0)),
        float(np.max(np.hypot(*since.T), initial=0.0)),
    )
    reach = max(BAND_EDGES * edge, BAND_TRAVEL * travel)
    near = cKDTree(points[motion.moving]).query(points, distance_upper_bound=reach)[0] <= reach
    return None if near.all() else near


def frame_mesh(motion: Motion, points: np.ndarray, point_data: dict | None = None) -> Mesh:
    """The motion's mesh at ``points`` (same cells, lines and groups)."""
    return dataclasses.replace(motion.mesh, points=points, point_data=point_data or {})


def remeshed(
    motion: Motion, points: np.ndarray, velocity: np.ndarray, frame: Contour
) -> tuple[Motion, np.ndarray]:
    """``frame`` meshed afresh (:func:`.pipeline.mesh_contour` at default options, in the
    same box for a far field) as a new :class:`Motion`, and ``velocity`` (one row per node
    of the motion's mesh at ``points``, the frame reached with the old triangles) carried
    to its nodes by linear interpolation in that mesh (the contour's own and the box's
    nodes: their velocity exactly)."""
    from .adapt import Locator, p1_values
    from .pipeline import mesh_contour

    exterior = motion.box is not None
    fresh = mesh_contour(frame, exterior=exterior, box=motion.box).mesh
    tri = motion.mesh.triangles
    first, w = Locator(points, tri).find(fresh.points)
    carried = p1_values(np.asarray(velocity, dtype=np.float64), tri, first, w)
    carried[: frame.n] = velocity[: frame.n]  # (the contour points: the same nodes)
    new = prepare(fresh.points, fresh.triangles, frame, frame.source)
    carried[new.held] = 0.0  # (the box is held: its nodes do not move, to the bit)
    return new, carried


#: What a fold message advises when a frame cannot be reached: at the last pseudo-time
#: step, and before it.
FRAME_ADVICE = (
    "the frame's points cannot be reached from the previous frame's without folding",
    "use more --steps, or frames closer together",
)


def move_frames(
    mesh_path: str,
    frame_paths: list[str],
    out_dir: str,
    options: MoveOptions | None = None,
    *,
    name: str | None = None,
    force: bool = False,
    on_frame: Callable[[int, int, Contour, dict], None] | None = None,
) -> dict:
    """What ``deformesh move`` does: carry the mesh in ``mesh_path`` along the frames.

    Every frame is read and checked before any work.  Frame ``k``'s mesh is written
    to ``out_dir/NAME_000k.FORMAT`` (``NAME`` is ``name`` or the mesh file's stem;
    frame 0 is the mesh itself), with ``velocity`` point data where the format has
    point data, and for ``.vtu`` the time series ``NAME.pvd`` of the frames written
    so far, even when a later frame fails.  No output may be an input, a symbolic link,
    or (unless ``force``) a sidecar deformesh did not write.
    ``on_frame(k, count, contour, record)`` is called after each frame.  Returns the
    summary (``per_frame``: one record a frame).  Raises :class:`.errors.FoldError`
    naming the frame that cannot be reached, and the frames already written.
    """
    o = MoveOptions() if options is None else options
    if not 0.0 <= o.min_angle < 60.0:  # (no triangle has all its angles above 60)
        raise OptionError(f"--min-angle must be from 0 to under 60 degrees, got {o.min_angle}")
    t0 = time.perf_counter()
    fmt = o.fmt.lower()
    stem = name or os.path.splitext(os.path.basename(mesh_path))[0]
    if name is not None and (
        not name or name in (".", "..") or os.sep in name or "/" in name or "\0" in name
    ):
        raise OptionError(
            f"--name {printable(name)}: a file name stem, without a folder (the frames go "
            "into --out-dir)"
        )
    points, tri, quads = formats.read_mesh(mesh_path, quads=True)
    if len(quads) and o.remesh:
        raise OptionError(
            f"{mesh_path}: --remesh meshes a frame afresh in triangles; a mesh with quads "
            "is carried with its own cells only (leave out --remesh)"
        )
    contours = [load_contour(f, None, o.decimal) for f in frame_paths]
    motion = prepare(points, tri, contours[0], mesh_path, quads)
    for c in contours[1:]:  # a bad frame fails before any work
        check_frame(motion, c)
    width = max(4, len(str(len(frame_paths))))
    frames = [
        os.path.join(out_dir, f"{stem}_{k:0{width}d}.{fmt}") for k in range(len(contours) + 1)
    ]
    pvd = [os.path.join(out_dir, f"{stem}.pvd")] if fmt == "vtu" else []
    inputs = [mesh_path, *frame_paths]
    formats.check_outputs(frames, fmt, inputs, typed=False, others=pvd, force=force)
    files.make_folder(out_dir)
    written: list[tuple[float, str]] = []
    records: list[dict] = []

    def write(k, pts, velocity, source, report):
        mesh = frame_mesh(motion, pts, {"velocity": velocity})
        file = os.path.basename(frames[k])
        formats.write_mesh(mesh, frames[k], fmt)
        written.append((k * o.dt, file))
        records.append({"frame": k, "input": source, "output": file, **report})

    first = quality.stats(motion.mesh)
    write(0, motion.mesh.points, np.zeros((len(points), 3)), mesh_path, first)
    floor = min(o.min_angle, first["min_angle"])  # (a mesh its contour holds lower)
    pts = motion.mesh.points
    try:
        for k, c in enumerate(contours, start=1):
            try:
                step = advance(motion, pts, c, o.steps, o.solver, o.solve, advice=FRAME_ADVICE)
            except FoldError as exc:
                raise FoldError(
                    f"{c.source}: frame {k} of {len(contours)} cannot be reached without "
                    f"folding: {exc}; frames 0-{k - 1} are in {out_dir}"
                ) from None
            velocity = np.column_stack([(step.points - pts) / o.dt, np.zeros(len(pts))])
            report = dict(step.report, remeshed=False)
            if step.report["min_angle"] < floor:
                if not o.remesh:
                    raise DegradedError(
                        f"{c.source}: frame {k} of {len(contours)}: its smallest angle "
                        f"{step.report['min_angle']:.3g} deg is under the floor {floor:.3g} "
                        f"(--min-angle); frames 0-{k - 1} are in {out_dir} (--remesh meshes "
                        "such a frame afresh and goes on)"
                    )
                motion, velocity = remeshed(motion, step.points, velocity, c)
                report = dict(step.report, **quality.stats(motion.mesh), remeshed=True)
                floor = min(o.min_angle, report["min_angle"])
            write(k, motion.mesh.points if report["remeshed"] else step.points, velocity,
                  c.source, report)  # fmt: skip
            pts = motion.mesh.points if report["remeshed"] else step.points
            if on_frame is not None:
                on_frame(k, len(contours), c, records[-1])
    finally:  # the time series of the frames written so far
        if pvd and written:
            files.write_bytes(formats.pvd_bytes(written), pvd[0])
    lowest = min(records, key=lambda r: r["min_angle"])
    again = [int(r["frame"]) for r in records if r.get("remeshed")]
    return {
        "mesh": mesh_path,
        "out_dir": out_dir,
        "format": fmt,
        "pvd": f"{stem}.pvd" if fmt == "vtu" else None,
        "frames": len(records),
        "nodes": records[0]["nodes"],
        "triangles": records[0]["triangles"],
        "quads": records[0].get("quads", 0),
        "min_angle": lowest["min_angle"],
        "min_angle_first": records[0]["min_angle"],
        "min_angle_frame": int(lowest["frame"]),
        "min_angle_floor": o.min_angle,
        "remeshed_frames": again,
        "seconds": round(time.perf_counter() - t0, 3),
        "per_frame": records,
    }
