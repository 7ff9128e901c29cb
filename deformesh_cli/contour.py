"""The contour model: validated, oriented closed rings (numpy arrays).

A :class:`Contour` is one or more closed rings (an outer boundary, holes,
separate parts).  It keeps the points in the order the user gave them (so
that mesh node ``k`` is input point ``k``) and remembers the line each came
from, so every message can say where a problem is.  Validation happens here,
before any meshing: per ring at least 3 distinct points, finite numbers, no
repeated consecutive point, non-zero area, no self-intersection; between
rings, no crossing or touching.  A closing point equal to a ring's first is
dropped; clockwise rings are walked counter-clockwise (``ccw_order``).
Nesting decides roles: a ring inside an odd number of others is a hole.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import shapely
from numpy.typing import ArrayLike

from .errors import InputError, LimitError, OptionError
from .geometry import next_on_ring, signed_area


@dataclass(frozen=True)
class Contour:
    """Closed rings, validated.

    Attributes
    ----------
    points : (m, 2) float64
        The points in input order, ring after ring, closing duplicates removed.
    lines : (m,) int64
        1-based line of the source each point came from (0 if not from a file).
    source : str
        Name used in messages (a path, or ``<stdin>``).
    starts : tuple of int
        Ring ``r`` is ``points[starts[r]:starts[r + 1]]``.
    ring_clockwise : tuple of bool
        Per ring: given clockwise (it is walked counter-clockwise).
    depth : tuple of int
        Per ring: how many other rings enclose it (odd: a hole).
    ring_labels : tuple of str
        Per ring: how messages name it (``ring 1`` unless the reader knows better,
        e.g. ``path#logo subpath 2`` for SVG).
    numbers : (m,) int64 or None
        Per point, the given point messages name it by (a derived contour's), or None.
    """

    points: np.ndarray
    lines: np.ndarray
    source: str = "<contour>"
    notes: tuple[str, ...] = field(default=())
    starts: tuple[int, ...] = ()
    ring_clockwise: tuple[bool, ...] = ()
    depth: tuple[int, ...] = ()
    ring_labels: tuple[str, ...] = ()
    #: per point, the input point messages name it by (a contour derived from another,
    #: the grid's with ears cut, names the given points); None: its own index
    numbers: np.ndarray | None = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        if not self.starts:
            object.__setattr__(self, "starts", (0, len(self.points)))
        if not self.ring_clockwise:
            object.__setattr__(self, "ring_clockwise", (False,) * self.n_rings)
        if not self.depth:
            object.__setattr__(self, "depth", (0,) * self.n_rings)
        if not self.ring_labels:
            object.__setattr__(self, "ring_labels", tuple(f"ring {r}" for r in range(self.n_rings)))

    @property
    def n(self) -> int:
        return len(self.points)

    @property
    def n_rings(self) -> int:
        return len(self.starts) - 1

    @property
    def clockwise(self) -> bool:
        """The first ring was given clockwise."""
        return self.ring_clockwise[0]

    @functools.cached_property
    def ring(self) -> np.ndarray:
        """Ring id of every point (computed once: loops index it per point; read-only)."""
        out = np.repeat(np.arange(self.n_rings), np.diff(self.starts))
        out.flags.writeable = False
        return out

    def ring_order(self, r: int) -> np.ndarray:
        """Input indices of ring ``r`` counter-clockwise, starting at its first point."""
        a, b = self.starts[r], self.starts[r + 1]
        idx = np.arange(a, b)
        if self.ring_clockwise[r]:
            idx = np.concatenate([[a], idx[:0:-1]])
        return idx

    @functools.cached_property
    def ccw_order(self) -> np.ndarray:
        """Every ring's :meth:`ring_order`, ring after ring (computed once; read-only)."""
        out = np.concatenate([self.ring_order(r) for r in range(self.n_rings)])
        out.flags.writeable = False
        return out

    @property
    def ccw_points(self) -> np.ndarray:
        return self.points[self.ccw_order]

    def is_hole(self, r: int) -> bool:
        return self.depth[r] % 2 == 1

    @property
    def area(self) -> float:
        """Area enclosed: outer rings minus holes."""
        return float(
            sum(
                (-1 if self.is_hole(r) else 1)
                * abs(signed_area(self.points[self.starts[r] : self.starts[r + 1]]))
                for r in range(self.n_rings)
            )
        )

    def ring_name(self, r: int) -> str:
        """``contour``, ``contour_2``, ... for outer rings; ``hole_1``, ... for holes."""
        holes = [q for q in range(self.n_rings) if self.is_hole(q)]
        if self.is_hole(r):
            return f"hole_{holes.index(r) + 1}"
        outer = [q for q in range(self.n_rings) if not self.is_hole(q)]
        k = outer.index(r)
        return "contour" if k == 0 else f"contour_{k + 1}"

    def where(self, k: int) -> str:
        """Human description of input point ``k``: index, ring, line and coordinates."""
        x, y = self.points[k]
        line = int(self.lines[k])
        parts = []
        r = int(np.searchsorted(self.starts, k, side="right")) - 1
        if self.n_rings > 1 or self.ring_labels[r] not in ("ring 0", ""):
            parts.append(self.ring_labels[r])
        if line:
            parts.append(f"line {line}")
        at = f" ({', '.join(parts)})" if parts else ""
        name = k if self.numbers is None else int(self.numbers[k])
        return f"point {name}{at} at ({x:.6g}, {y:.6g})"

    def edge_lengths(self) -> np.ndarray:
        """Length of the edge from each point to the next point on its ring."""
        d = self.points[next_on_ring(self.ring)] - self.points
        return np.hypot(d[:, 0], d[:, 1])

    def min_spacing(self) -> tuple[float, int, int]:
        """Smallest distance between any two contour points, and the two points.

        By shapely's STRtree (shapely is loaded anyway; importing scipy.spatial on
        every run costs start-up time).  Checked: the same distance and the same two
        points as scipy's cKDTree on every sample, reference and corpus contour.
        """
        g = shapely.points(self.points)
        (src, dst), dist = shapely.STRtree(g).query_nearest(
            g, exclusive=True, return_distance=True, all_matches=False
        )
        k = int(np.argmin(dist))
        return float(dist[k]), int(src[k]), int(dst[k])


def make_contour(
    points: ArrayLike,
    lines: ArrayLike | None = None,
    source: str = "<contour>",
    ring_starts: Sequence[int] | None = None,
    ring_labels: Sequence[str] | None = None,
    clockwise_by_convention: Sequence[bool] | None = None,
) -> Contour:
    """Validate the points of one or more closed rings and return a :class:`Contour`.

    ``ring_starts`` gives the index where each ring starts (default: one ring);
    ``ring_labels`` how messages name each ring (default ``ring 0``, ...);
    ``clockwise_by_convention``: per ring, whether its format asks for it clockwise
    (GeoJSON's holes): such a ring read clockwise gets no note.
    """
    p = np.array(points, dtype=np.float64, copy=True)
    if p.ndim != 2 or p.shape[1] != 2:
        raise InputError(f"{source}: expected (m, 2) points, got shape {p.shape}")
    ln = np.zeros(len(p), dtype=np.int64) if lines is None else np.asarray(lines, np.int64)
    if not np.isfinite(p).all():
        r = int(np.argmax(~np.isfinite(p).all(axis=1)))
        raise InputError(f"{source}: point {r} has a non-finite coordinate")
    check_scale(p, source)
    bounds = list(ring_starts if ring_starts is not None else [0]) + [len(p)]
    notes: list[str] = []
    pts, lns, starts, cw = [], [], [0], []
    for r in range(len(bounds) - 1):
        rp, rl = p[bounds[r] : bounds[r + 1]], ln[bounds[r] : bounds[r + 1]]
        label = ring_labels[r] if ring_labels is not None else f"ring {r}"
        name = f"{label}: " if len(bounds) > 2 or ring_labels is not None else ""
        if len(rp) > 1 and np.array_equal(rp[0], rp[-1]):
            rp, rl = rp[:-1], rl[:-1]
            notes.append(f"{name}dropped the closing point (equal to the first)")
        ring = _check_ring(rp, rl, source, name, starts[-1])
        _check_resolution(rp, float(np.abs(p).max()), source, name, starts[-1])
        usual = clockwise_by_convention is not None and clockwise_by_convention[r]
        if ring < 0 and not usual:
            notes.append(f"{name}re-oriented clockwise input to counter-clockwise")
        pts.append(rp)
        lns.append(rl)
        starts.append(starts[-1] + len(rp))
        cw.append(ring < 0)
    p, ln = np.concatenate(pts), np.concatenate(lns)
    labels = tuple(ring_labels) if ring_labels is not None else ()
    c = Contour(p, ln, source, starts=tuple(starts), ring_clockwise=tuple(cw), ring_labels=labels)
    depth = _check_rings_apart(c)
    return Contour(
        p,
        ln,
        source,
        notes=tuple(notes),
        starts=tuple(starts),
        ring_clockwise=tuple(cw),
        depth=depth,
        ring_labels=labels,
    )


#: Coordinates beyond this are refused: their squares (areas, distances) overflow.
MAX_COORDINATE = 1e150

#: A contour smaller than this share of its distance from the origin is refused: its
#: span would be under 500 units in the last place of its coordinates, and the grid's
#: step below their resolution (a contour of 1e-6 at 1e6, 1e-12 of its offset,
#: meshes with the contract: ``tests/test_bad_input.py``).
MIN_RELATIVE_SPAN = 1e-13

#: An edge shorter than this share of the contour's largest coordinate is refused: it
#: is under 50 units in the last place, and the cells by it would be a few (a circle of
#: 1e-6 at 1e6, edges 7e-14 of the offset, meshes with the contract).
MIN_RELATIVE_EDGE = 1e-14


def grown_box(contour: Contour, lo, hi, margin: float) -> tuple[float, float, float, float]:
    """The contour's box ``lo``, ``hi`` grown by ``margin`` on every side, within the
    coordinates the contour may have (else an :class:`OptionError` naming ``--margin``)."""
    box = (
        float(lo[0] - margin),
        float(lo[1] - margin),
        float(hi[0] + margin),
        float(hi[1] + margin),
    )
    if not max(abs(v) for v in box) <= MAX_COORDINATE:
        raise OptionError(
            f"{contour.source}: --margin {margin:g} puts the box's sides beyond "
            f"{MAX_COORDINATE:g} of 0, where its areas would overflow"
        )
    return box


def far_field_box(contour: Contour, margin: float | None = None):
    """An exterior mesh's default box: the contour's box grown by ``margin``, by default
    its larger extent (:func:`grown_box`)."""
    lo, hi = contour.points.min(axis=0), contour.points.max(axis=0)
    return grown_box(contour, lo, hi, float((hi - lo).max()) if margin is None else margin)


def check_scale(p: np.ndarray, source: str) -> None:
    """What double precision cannot mesh, refused with the place: coordinates whose
    squares overflow, a contour so small for its offset that its points sit a few
    doubles apart, or so small that its squares underflow."""
    if len(p) == 0:
        return
    big = np.abs(p).max(axis=1)
    if big.max() > MAX_COORDINATE:
        k = int(np.argmax(big))
        raise InputError(
            f"{source}: point {k} at ({p[k, 0]:.6g}, {p[k, 1]:.6g}) is beyond "
            f"{MAX_COORDINATE:g}: areas and grid sizes would overflow in double precision; "
            "scale the contour down"
        )
    span = float(np.ptp(p, axis=0).max())
    if 0 < span < MIN_RELATIVE_SPAN * float(big.max()):
        raise InputError(
            f"{source}: the contour spans {span:.3g} at {float(big.max()):.3g} from the "
            "origin: its grid would step below the coordinates' resolution; shift it "
            "near the origin"
        )
    if 0 < span < 1 / MAX_COORDINATE:
        raise InputError(
            f"{source}: the contour spans {span:.3g}: its areas would underflow in double "
            "precision; scale it up"
        )


def _check_resolution(p: np.ndarray, big: float, source: str, name: str, offset: int) -> None:
    """Refuse an edge shorter than :data:`MIN_RELATIVE_EDGE` of the contour's largest
    coordinate: the grid there would step below the coordinates' resolution."""
    length = np.hypot(*(np.roll(p, -1, axis=0) - p).T)
    k = int(np.argmin(length))
    if length[k] < MIN_RELATIVE_EDGE * big:
        raise InputError(
            f"{source}: {name}point {k + offset} at ({p[k, 0]:.6g}, {p[k, 1]:.6g}): its edge "
            f"to the next point is {length[k]:.3g} long, with coordinates up to {big:.3g}: "
            "the grid there would step below the coordinates' resolution"
        )


def _check_ring(p: np.ndarray, ln: np.ndarray, source: str, name: str, offset: int) -> float:
    """Validate one ring (global indices start at ``offset``); return its signed area."""
    other = (p != p[0]).any(axis=1)  # (distinct points: one, a second, a third?)
    third = other & (p != p[int(np.argmax(other))]).any(axis=1)
    if not third.any():
        raise InputError(
            f"{source}: {name}fewer than 3 distinct points ({1 + int(other.any())}); "
            "a contour needs at least 3"
        )
    c = Contour(p, ln, source, ring_labels=(name.removesuffix(": "),) if name else ())

    def where(k):
        return c.where(k).replace(f"point {k}", f"point {k + offset}", 1)

    same = np.all(p == np.roll(p, -1, axis=0), axis=1)
    if same.any():
        k = int(np.argmax(same))
        raise InputError(
            f"{source}: {where((k + 1) % len(p))} repeats the previous point; remove the duplicate"
        )
    area = signed_area(p)
    span = float(np.ptp(p, axis=0).max())
    d = p - p[0]
    far = d[np.argmax(np.hypot(d[:, 0], d[:, 1]))]
    if np.abs(d[:, 0] * far[1] - d[:, 1] * far[0]).max() <= 1e-13 * span * span:
        raise InputError(f"{source}: {name}the contour encloses no area (all points are collinear)")
    _check_simple(c, where)
    return area


def _check_rings_apart(c: Contour) -> tuple[int, ...]:
    """Raise if two rings cross or touch; return each ring's nesting depth."""
    R = c.n_rings
    if R == 1:
        return (0,)
    rings = [c.points[c.starts[r] : c.starts[r + 1]] for r in range(R)]
    geoms = np.array([shapely.LinearRing(q) for q in rings], dtype=object)
    tree = shapely.STRtree(geoms)
    a, b = tree.query(geoms, predicate="intersects")
    keep = a < b
    if keep.any():
        i, j = int(a[keep][0]), int(b[keep][0])
        x, y = shapely.get_coordinates(shapely.intersection(geoms[i], geoms[j]))[0]
        raise InputError(
            f"{c.source}: {c.ring_labels[j]} touches or crosses {c.ring_labels[i]} near "
            f"({x:.6g}, {y:.6g}); rings must be apart"
        )
    return tuple(ring_nesting(rings)[0].tolist())


def ring_nesting(rings: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``(depth, parent)`` of rings that are apart: how many rings hold each, and the
    innermost of them (-1: none).  One spatial index query: the cost grows with the
    pairs that nest, not with all pairs."""
    polys = shapely.polygons([shapely.LinearRing(q) for q in rings])
    first = shapely.points([q[0] for q in rings])
    inner, outer = shapely.STRtree(polys).query(first, predicate="within")
    depth = np.bincount(inner, minlength=len(rings))
    parent = np.full(len(rings), -1, dtype=np.int64)
    order = np.argsort(depth[outer], kind="stable")  # (the deepest holder written last)
    parent[inner[order]] = outer[order]
    return depth, parent


def _check_simple(c: Contour, where=None) -> None:
    """Raise InputError naming the first pair of crossing or touching edges."""
    where = where or c.where
    p = c.points
    closed = np.vstack([p, p[:1]])
    if shapely.is_simple(shapely.linearrings(closed)):
        return
    m = len(p)
    segs = shapely.linestrings(np.stack([p, np.roll(p, -1, axis=0)], axis=1))
    tree = shapely.STRtree(segs)
    i, j = tree.query(segs, predicate="intersects")
    keep = i < j
    i, j = i[keep], j[keep]
    adjacent = (j == i + 1) | ((i == 0) & (j == m - 1))
    # adjacent edges share a point; they are a problem only when they overlap
    inter = shapely.intersection(segs[i], segs[j])
    bad = ~adjacent | (shapely.length(inter) > 0)
    if not bad.any():  # shapely said not simple; be conservative but precise
        raise InputError(f"{c.source}: the contour intersects itself")
    order = np.lexsort((j[bad], i[bad]))
    a, b = int(i[bad][order[0]]), int(j[bad][order[0]])
    at = shapely.get_coordinates(shapely.intersection(segs[a], segs[b]))
    x, y = at[0] if len(at) else p[a]
    verb = "overlaps" if (b == a + 1 or (a == 0 and b == m - 1)) else "crosses"
    raise InputError(
        f"{c.source}: the contour intersects itself near ({x:.6g}, {y:.6g}): edge from "
        f"{where(a)} {verb} edge from {where(b)}"
    )


def parse_spacing(value: str | float, contour: Contour, option: str = "--resample") -> float:
    """A length option: a number in contour units, or ``P%`` of the contour's diagonal."""
    s = str(value).strip()
    try:
        v = float(s.rstrip("%"))
    except ValueError:
        raise OptionError(f"{option} {value!r} is not a number (or a percentage)") from None
    if s.endswith("%"):
        v *= float(np.hypot(*np.ptp(contour.points, axis=0))) / 100
    if not (np.isfinite(v) and v > 0):
        raise OptionError(f"{option} must be > 0, got {value!r}")
    return v


#: A vertex turning by more than this (degrees) is a corner that resampling keeps.
CORNER_DEGREES = 30.0


def ring_corners(p: np.ndarray) -> np.ndarray:
    """Indices of one ring's vertices turning by more than :data:`CORNER_DEGREES`."""
    d_in = p - np.roll(p, 1, axis=0)
    d_out = np.roll(p, -1, axis=0) - p
    turn = np.degrees(
        np.abs(
            np.arctan2(
                d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0], (d_in * d_out).sum(axis=1)
            )
        )
    )
    return np.flatnonzero(turn > CORNER_DEGREES)


def count_words(x: float) -> str:
    """A count for a message: ``12,345``, or ``6.28e+20`` when it is too long to read."""
    return f"{x:,.0f}" if x < 1e12 else f"{x:.3g}"


#: The most points :func:`resample` makes (a contour of more asks for more grid nodes than
#: the default ``--max-nodes``).
MAX_RESAMPLED = 8_000_000


def resample(contour: Contour, spacing: float) -> Contour:
    """The contour re-spaced: each ring's corners (turning > :data:`CORNER_DEGREES`) kept,
    the pieces between them cut into equal chords about ``spacing`` long.

    The given points are no longer the boundary nodes (a note says so); the result is
    validated like any contour.
    """
    wanted = float(contour.edge_lengths().sum()) / spacing  # (counted before any array)
    if not wanted <= MAX_RESAMPLED:
        raise LimitError(
            f"{contour.source}: --resample {spacing:g} would give about "
            f"{count_words(wanted)} points, over {MAX_RESAMPLED:,}; give a larger spacing"
        )
    pts, starts, notes = [], [0], []
    for r in range(contour.n_rings):
        p = contour.points[contour.ring_order(r)]
        corners = ring_corners(p)
        if len(corners) == 0:
            corners = np.array([0])
        new = []
        for a, b in zip(corners, np.roll(corners, -1)):
            idx = np.arange(a, b + 1 if b > a else b + len(p) + 1) % len(p)
            piece = p[idx]
            seg = np.hypot(*np.diff(piece, axis=0).T)
            cum = np.concatenate([[0.0], np.cumsum(seg)])
            k = max(1, int(round(cum[-1] / spacing)))
            s = cum[-1] * np.arange(k) / k
            new.append(
                np.column_stack([np.interp(s, cum, piece[:, 0]), np.interp(s, cum, piece[:, 1])])
            )
        ring = np.vstack(new)
        pts.append(ring)
        starts.append(starts[-1] + len(ring))
        notes.append(
            f"{contour.ring_name(r)}: resampled {len(p)} points to {len(ring)} at "
            f"spacing {spacing:.3g} (corners kept); the given points are not all "
            "boundary nodes"
        )
    c = make_contour(
        np.concatenate(pts),
        None,
        contour.source,
        ring_starts=starts[:-1],
        ring_labels=list(contour.ring_labels),
    )
    return Contour(
        c.points,
        c.lines,
        c.source,
        notes=tuple(contour.notes) + tuple(notes),
        starts=c.starts,
        ring_clockwise=c.ring_clockwise,
        depth=c.depth,
        ring_labels=c.ring_labels,
    )


def split_edges(
    c: Contour, h: float | None, max_points: int | None = None
) -> tuple[Contour, np.ndarray | None]:
    """``c`` with every edge longer than ``h`` split into equal pieces (``ceil(L / h)``
    of them), and where each given point is in it: ``(fine, given)``, point ``k`` of
    ``c`` being point ``given[k]`` of ``fine``; ``(c, None)`` where nothing is split
    (``h`` None, or no edge longer).  The given points keep their exact coordinates
    and order; the added ones lie on their edge (rounded to the nearest double) and
    carry its first point's source line.  Raises :class:`LimitError` past
    ``max_points``."""
    if h is None:
        return c, None
    p = c.points
    nxt = next_on_ring(c.ring)
    length = np.hypot(*(p[nxt] - p).T)
    wanted = np.maximum(1.0, np.ceil(length / h))  # (floats: counted before any array)
    total_f = float(wanted.sum())
    if max_points is not None and total_f > max_points:
        raise LimitError(
            f"{c.source}: --max-h {h:g} splits the contour into {count_words(total_f)} "
            f"boundary nodes, over --max-nodes {max_points:,}"
        )
    pieces = wanted.astype(np.int64)
    total = int(pieces.sum())
    if total == len(p):
        return c, None
    given = np.cumsum(pieces) - pieces
    edge = np.repeat(np.arange(len(p)), pieces)
    t = (np.arange(total) - given[edge]) / pieces[edge]
    fine = p[edge] + t[:, None] * (p[nxt] - p)[edge]
    fine[given] = p  # (bit for bit)
    starts = [int(given[s]) for s in c.starts[:-1]] + [total]
    out = Contour(
        fine,
        c.lines[edge],
        c.source,
        notes=c.notes,
        starts=tuple(starts),
        ring_clockwise=c.ring_clockwise,
        depth=c.depth,
        ring_labels=c.ring_labels,
    )
    return out, given
