"""Contour input: CSV text -> a validated, counter-clockwise closed ring.

A :class:`Contour` keeps the points in the order the user gave them (so that
mesh node ``k`` is input point ``k``) and remembers the line each came from,
so every message can say where a problem is.  Validation happens here, before
any meshing: at least 3 distinct points, finite numbers, no repeated
consecutive point, non-zero area, no self-intersection.  A closing point equal
to the first is dropped; clockwise input is re-oriented (``ccw_order``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import shapely

from .errors import InputError

_DELIMITERS = (",", ";", "\t")


@dataclass(frozen=True)
class Contour:
    """A closed contour, validated.

    Attributes
    ----------
    points : (m, 2) float64
        The points in input order, the closing duplicate removed.
    lines : (m,) int64
        1-based line of the source each point came from (0 if not from a file).
    source : str
        Name used in messages (a path, or ``<stdin>``).
    clockwise : bool
        True when the input was clockwise (it is meshed counter-clockwise).
    """

    points: np.ndarray
    lines: np.ndarray
    source: str = "<contour>"
    clockwise: bool = False
    notes: tuple[str, ...] = field(default=())

    @property
    def n(self) -> int:
        return len(self.points)

    @property
    def ccw_order(self) -> np.ndarray:
        """Indices of the input points in counter-clockwise order, starting at point 0."""
        idx = np.arange(self.n)
        if self.clockwise:
            idx = np.concatenate([[0], idx[:0:-1]])
        return idx

    @property
    def ccw_points(self) -> np.ndarray:
        return self.points[self.ccw_order]

    @property
    def area(self) -> float:
        return abs(signed_area(self.points))

    def where(self, k: int) -> str:
        """Human description of input point ``k``: index, line and coordinates."""
        x, y = self.points[k]
        line = int(self.lines[k])
        at = f" (line {line})" if line else ""
        return f"point {k}{at} at ({x:.6g}, {y:.6g})"

    def min_spacing(self) -> tuple[float, int, int]:
        """Smallest distance between any two contour points, and the two points."""
        from scipy.spatial import cKDTree

        dist, nb = cKDTree(self.points).query(self.points, k=2)
        k = int(np.argmin(dist[:, 1]))
        return float(dist[k, 1]), k, int(nb[k, 1])


def signed_area(p: np.ndarray) -> float:
    """Shoelace area of a closed polygon given without its closing point."""
    x, y = p[:, 0], p[:, 1]
    # subtract a reference point: keeps precision for large offsets
    x = x - x[0]
    y = y - y[0]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def load_contour(path: str | Path, data: bytes | None = None) -> Contour:
    """Read a contour file (CSV).  ``path == "-"`` with ``data`` reads bytes given."""
    name = "<stdin>" if str(path) == "-" else str(path)
    if data is None:
        p = Path(path)
        if not p.exists():
            raise InputError(f"{name}: no such file")
        if p.is_dir():
            raise InputError(f"{name}: is a directory, not a contour file")
        try:
            data = p.read_bytes()
        except OSError as exc:
            raise InputError(f"{name}: cannot read: {exc.strerror}") from None
    suffix = Path(name).suffix.lower()
    if suffix == ".svg":
        raise InputError(f"{name}: SVG input is not supported yet; give a CSV of x,y points")
    if b"\x00" in data[:4096]:
        raise InputError(f"{name}: binary file, expected CSV text with x,y columns")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(
            f"{name}: not UTF-8 text (byte {exc.start}); expected CSV with x,y columns"
        ) from None
    return parse_csv(text, name)


_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^[+-]?(nan|inf|infinity)$", re.I)


def _split(line: str, delim: str | None) -> list[str]:
    if delim is None:
        return line.split()
    return [f.strip() for f in line.split(delim)]


def parse_csv(text: str, source: str = "<contour>") -> Contour:
    """Parse CSV text into a validated :class:`Contour`.

    Accepts an optional header naming ``x``, ``y`` (and ``ring``), ``#``
    comments, blank lines, and ``,`` ``;`` tab or whitespace delimiters (the
    first data line decides).  Raises :class:`InputError` naming the line.
    """
    text = text.removeprefix("\ufeff")
    rows: list[tuple[int, list[str]]] = []
    delim: str | None = None
    decided = False
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if not decided:
            delim = next((d for d in _DELIMITERS if d in line), None)
            decided = True
        rows.append((lineno, _split(line, delim)))
    if not rows:
        raise InputError(f"{source}: empty: no points (expected CSV with x,y columns)")

    cols = {"x": 0, "y": 1}
    ring_col: int | None = None
    first_line, first = rows[0]
    if not all(_NUMBER.match(f) for f in first if f):
        names = [f.strip().strip('"').strip("'").lower() for f in first]
        if "x" not in names or "y" not in names:
            raise InputError(
                f"{source}: line {first_line}: header {','.join(first)!r} must name "
                "columns x and y"
            )
        cols = {"x": names.index("x"), "y": names.index("y")}
        if "ring" in names:
            ring_col = names.index("ring")
        ncols = len(names)
        rows = rows[1:]
        if not rows:
            raise InputError(f"{source}: no points after the header (line {first_line})")
    else:
        ncols = len(first)
        if ncols < 2:
            raise InputError(
                f"{source}: line {first_line}: expected 2 columns x,y, got {ncols}"
            )
        if ncols >= 3:
            ring_col = 2
    need = max(max(cols.values()), ring_col if ring_col is not None else 0) + 1

    xy = np.empty((len(rows), 2))
    lines = np.empty(len(rows), dtype=np.int64)
    rings = np.zeros(len(rows), dtype=np.int64)
    for r, (lineno, fields) in enumerate(rows):
        if len(fields) < need or (len(fields) != ncols and ncols > need):
            raise InputError(
                f"{source}: line {lineno}: expected {ncols} columns, got {len(fields)}"
            )
        for c, key in enumerate(("x", "y")):
            f = fields[cols[key]]
            if not _NUMBER.match(f):
                raise InputError(f"{source}: line {lineno}: {key} value {f!r} is not a number")
            xy[r, c] = float(f)
        if ring_col is not None:
            f = fields[ring_col]
            try:
                rings[r] = int(float(f))
            except ValueError:
                raise InputError(
                    f"{source}: line {lineno}: ring value {f!r} is not an integer"
                ) from None
        lines[r] = lineno
    bad = ~np.isfinite(xy).all(axis=1)
    if bad.any():
        r = int(np.argmax(bad))
        raise InputError(
            f"{source}: line {lines[r]}: point {r} has a non-finite coordinate "
            f"({xy[r, 0]}, {xy[r, 1]})"
        )
    if len(np.unique(rings)) > 1:
        r = int(np.argmax(rings != rings[0]))
        raise InputError(
            f"{source}: line {lines[r]}: several rings (holes) are not supported yet; "
            "give one closed contour"
        )
    return make_contour(xy, lines, source)


def make_contour(points, lines=None, source: str = "<contour>") -> Contour:
    """Validate points of one closed ring and return a :class:`Contour`."""
    p = np.array(points, dtype=np.float64, copy=True)
    if p.ndim != 2 or p.shape[1] != 2:
        raise InputError(f"{source}: expected (m, 2) points, got shape {p.shape}")
    ln = np.zeros(len(p), dtype=np.int64) if lines is None else np.asarray(lines, np.int64)
    notes: list[str] = []
    if not np.isfinite(p).all():
        r = int(np.argmax(~np.isfinite(p).all(axis=1)))
        raise InputError(f"{source}: point {r} has a non-finite coordinate")
    if len(p) > 1 and np.array_equal(p[0], p[-1]):
        p, ln = p[:-1], ln[:-1]
        notes.append("dropped the closing point (equal to the first)")
    if len(np.unique(p, axis=0)) < 3:
        raise InputError(
            f"{source}: fewer than 3 distinct points ({len(np.unique(p, axis=0))}); "
            "a contour needs at least 3"
        )
    c = Contour(p, ln, source)
    same = np.all(p == np.roll(p, -1, axis=0), axis=1)
    if same.any():
        k = int(np.argmax(same))
        raise InputError(
            f"{source}: {c.where((k + 1) % len(p))} repeats the previous point; "
            "remove the duplicate"
        )
    area = signed_area(p)
    span = float(np.ptp(p, axis=0).max())
    d = p - p[0]
    far = d[np.argmax(np.hypot(d[:, 0], d[:, 1]))]
    if np.abs(d[:, 0] * far[1] - d[:, 1] * far[0]).max() <= 1e-13 * span * span:
        raise InputError(f"{source}: the contour encloses no area (all points are collinear)")
    _check_simple(c)
    if area < 0:
        notes.append("re-oriented clockwise input to counter-clockwise")
    return Contour(p, ln, source, clockwise=area < 0, notes=tuple(notes))


def _check_simple(c: Contour) -> None:
    """Raise InputError naming the first pair of crossing or touching edges."""
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
    where = shapely.get_coordinates(shapely.intersection(segs[a], segs[b]))
    x, y = where[0] if len(where) else p[a]
    verb = "overlaps" if (b == a + 1 or (a == 0 and b == m - 1)) else "crosses"
    raise InputError(
        f"{c.source}: the contour intersects itself near ({x:.6g}, {y:.6g}): edge from "
        f"{c.where(a)} {verb} edge from {c.where(b)}"
    )
