"""SVG input: filled shapes -> closed rings -> a validated :class:`Contour`.

svgelements (pinned) parses the file and applies transforms and the viewBox
(coordinates come out in viewport units).  Every path vertex (segment
endpoint) becomes a contour point; curves (quadratic and cubic Beziers,
elliptical arcs) are flattened by uniform parameter steps, as few as keep the
chord within ``tolerance`` of the curve (bound: chord gap <= max|C''| dt^2 / 8).
y is flipped (SVG's y points down): ``y -> height - y`` with the viewport
height (``y -> -y`` if the file gives neither height nor viewBox).  Each
subpath is a ring; the region is what a renderer fills (:func:`_filled_region`):
each element's fill rule (``nonzero`` or ``evenodd``) by winding number, the
elements' union.  Rings that meet nothing and bound filled area come out as
given; where subpaths touch or cross, the boundary of the filled area is noded
at the crossings.  Elements of different fills that overlap, and an area that
pinches to a point, are refused; ``--id`` picks one element.
"""

from __future__ import annotations

import dataclasses
import io
import math
import re
import warnings
import zlib

import numpy as np
import shapely
import svgelements as se

from ..contour import MAX_COORDINATE, Contour, check_scale, make_contour
from ..errors import InputError, OptionError, printable

#: Default chord tolerance, as a fraction of the drawing's bounding-box diagonal.
DEFAULT_RELATIVE_TOLERANCE = 1e-3
#: Most pieces one curve segment is cut into (guards against a tiny tolerance).
MAX_PIECES = 10_000
#: Most elements a drawing may hold with its ``<use>`` references expanded.
MAX_ELEMENTS = 10_000
#: Deepest chain of ``<use>`` references (a use of a group that uses ...).
MAX_USE_DEPTH = 16


def parse_tolerance(value: str | float | None) -> tuple[float, bool] | None:
    """``--tolerance`` text -> (value, relative).  ``0.5%`` is relative to the diagonal."""
    if value is None:
        return None
    if isinstance(value, (int, float)):
        tol, rel = float(value), False
    else:
        s = value.strip()
        rel = s.endswith("%")
        try:
            tol = float(s.rstrip("%")) / (100 if rel else 1)
        except ValueError:
            raise OptionError(f"--tolerance {value!r} is not a number (or a percentage)") from None
    if not (math.isfinite(tol) and tol > 0):
        raise OptionError(f"--tolerance must be > 0, got {value!r}")
    return tol, rel


def read_svg(
    data: bytes,
    source: str,
    tolerance=None,
    element_id: str | None = None,
    gzipped=False,
    stroke: bool = False,
) -> Contour:
    """An SVG or gzip-compressed SVG file's bytes as a :class:`Contour` (:func:`parse_svg`)."""
    if gzipped or data[:2] == b"\x1f\x8b":
        import gzip

        try:
            data = gzip.decompress(data)
        except (OSError, EOFError, zlib.error) as exc:  # (a truncated file: EOFError)
            why = str(exc) or type(exc).__name__
            raise InputError(f"{source}: not a readable gzip-compressed SVG: {why}") from None
    return parse_svg(data, source, tolerance, element_id, stroke)


def parse_svg(
    data: bytes,
    source: str = "<svg>",
    tolerance=None,
    element_id: str | None = None,
    stroke: bool = False,
) -> Contour:
    """Read SVG bytes into a validated :class:`Contour` (see the module docstring).

    ``tolerance`` is ``None`` (1/1000 of the drawing's diagonal), a number in
    drawing units, or the text of ``--tolerance`` (``0.5%`` = relative).
    ``stroke``: mesh the outline of the stroked shapes instead of the filled ones
    (:func:`_stroke_rings`).
    """
    tol_spec = parse_tolerance(tolerance)
    _check_encoding(data, source)
    _check_references(data, source)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            svg = se.SVG.parse(io.BytesIO(data), reify=True)
    except Exception as exc:  # xml.etree.ParseError and svgelements' own errors
        raise InputError(f"{source}: not a readable SVG file: {_one_line(exc)}") from None
    if not isinstance(svg, se.SVG):  # an XML or HTML document whose root is no <svg>
        root = re.search(rb"<([A-Za-z_][\w:.-]*)", re.sub(rb"<[?!][^>]*>", b"", data[:4096]))
        what = f"<{root.group(1).decode('ascii', 'replace')}>" if root else "not <svg>"
        raise InputError(f"{source}: not an SVG document: its root element is {what}")
    shapes = _pick_shapes(svg, source, element_id, _stroked if stroke else _filled)
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        boxes = np.array([s.bbox() for s in shapes if s.bbox() is not None], dtype=float)
    if not (np.abs(boxes) <= MAX_COORDINATE).all():  # (NaN fails the test too)
        raise InputError(
            f"{source}: a shape reaches beyond {MAX_COORDINATE:g}: areas and grid sizes "
            "would overflow in double precision; scale the drawing down"
        )
    if len(boxes) == 0:
        raise InputError(f"{source}: the SVG's shapes are empty")
    diag = math.hypot(boxes[:, 2].max() - boxes[:, 0].min(), boxes[:, 3].max() - boxes[:, 1].min())
    if tol_spec is None:
        tol = DEFAULT_RELATIVE_TOLERANCE * diag
    else:
        tol = tol_spec[0] * (diag if tol_spec[1] else 1.0)
    # flip about the viewport's height; an SVG giving neither height nor viewBox
    # has no page to flip in (svgelements would assume 1000 px): y -> -y
    sized = svg.values.get("height") is not None or svg.viewbox is not None
    height = float(svg.height) if sized and svg.height else 0.0
    if stroke:
        rings, labels, notes = _stroke_rings(shapes, tol, height, 1e-9 * diag, source)
        starts = np.cumsum([0] + [len(r) for r in rings])[:-1]
        c = make_contour(
            np.concatenate(rings), None, source, ring_starts=starts, ring_labels=labels
        )
        return dataclasses.replace(c, notes=tuple(notes))

    rings, labels, element, evenodd, notes = _collect_rings(
        shapes, tol, height, 1e-9 * diag, source
    )
    if not rings:
        hint = (
            "; give --stroke to mesh their strokes' outline" if any(map(_stroked, shapes)) else ""
        )
        raise InputError(f"{source}: no filled area in the SVG (every subpath is empty){hint}")
    paints = [_paint(shape) for shape in shapes]
    rings, labels, more = _filled_region(
        rings, labels, element, evenodd, paints, shapes, 1e-9 * diag, source
    )
    notes += more
    starts = np.cumsum([0] + [len(r) for r in rings])[:-1]
    c = make_contour(np.concatenate(rings), None, source, ring_starts=starts, ring_labels=labels)
    notes.insert(
        0,
        f"read {len(rings)} ring(s) from {len(shapes)} SVG shape(s), curves "
        f"flattened to a chord tolerance of {tol:.3g}",
    )
    return dataclasses.replace(c, notes=tuple(notes))


def _collect_rings(shapes, tol: float, height: float, eps: float, source: str):
    """Every subpath of every shape as a ring, flipped, repeats dropped, flat ones skipped.

    Returns parallel lists: rings, labels, owning shape, evenodd?, and notes.
    A subpath left open (no ``Z``) is closed by a straight edge from its end to its
    start, as SVG fills it (a note says so).
    """
    rings, labels, element, evenodd, notes = [], [], [], [], []
    for k, shape in enumerate(shapes):
        name = _label(shape, k)
        rule = str(shape.values.get("fill-rule", "nonzero")).strip().lower()
        for j, (ring, closed) in enumerate(_subpaths(se.Path(shape), tol, f"{source}: {name}")):
            ring[:, 1] = height - ring[:, 1]  # height 0: y -> -y
            check_scale(ring, source)  # (before any product of coordinates overflows)
            gap = float(np.hypot(*(ring[-1] - ring[0])))
            if not closed and eps < gap <= tol and len(ring) > 3:
                # an open subpath ending within the chord tolerance of its start (rounded
                # coordinates, as minified icons have): its end is its start
                ring = ring[:-1]
                notes.append(
                    f"closed subpath {j + 1} of {name}: its end was {gap:.3g} from "
                    "its start (within --tolerance)"
                )
                gap = 0.0
            exact = len(_drop_repeats(ring, eps))
            # points closer than the tolerance to the last one kept are the same point at
            # the drawing's precision (minified icons round 0.0005 away from their start)
            ring = _merge_close(_drop_repeats(ring, eps), max(eps, tol))
            if len(ring) < exact:
                notes.append(
                    f"merged {exact - len(ring)} point(s) of {name} subpath {j + 1} "
                    f"closer than the tolerance {tol:.3g} to the previous one"
                )
            if _flat(ring):
                notes.append(f"skipped subpath {j + 1} of {name}: it encloses no area")
                continue
            if not closed and gap > eps:
                # SVG fills an open subpath as if a closepath joined its end to its start
                # (SVG 2, 'fill' painting): so does the contour, and says so
                (x0, y0), (x1, y1) = ring[0], ring[-1]
                notes.append(
                    f"closed {name} subpath {j + 1} as SVG fills it: a straight edge from its "
                    f"end at ({x1:.6g}, {y1:.6g}) back to its start at ({x0:.6g}, {y0:.6g}), "
                    f"{gap:.3g} long"
                )
            rings.append(ring)
            labels.append(f"{name} subpath {j + 1}")
            element.append(k)
            evenodd.append(rule == "evenodd")
    return rings, labels, element, evenodd, notes


#: The encodings an SVG may declare (those XML parsers must read, and Latin-1).
ENCODINGS = ("utf-8", "utf8", "utf-16", "utf-16le", "utf-16be", "us-ascii", "ascii",
             "iso-8859-1", "iso8859-1", "latin-1", "latin1")  # fmt: skip
_DECLARED = re.compile(r"\A\s*<\?xml\b[^>]*?\bencoding\s*=\s*([\"'])(.*?)\1", re.DOTALL)


def _check_encoding(data: bytes, source: str) -> None:
    """Refuse an XML declaration naming an encoding outside :data:`ENCODINGS` (before any
    parser looks the name up among the codecs Python happens to have)."""
    utf16 = data[:2] in (b"\xff\xfe", b"\xfe\xff")
    head = data[:1024].decode("utf-16" if utf16 else "latin-1", errors="ignore").lstrip("\ufeff")
    m = _DECLARED.match(head)
    if m is not None and m.group(2).strip().lower().replace("_", "-") not in ENCODINGS:
        raise InputError(
            f"{source}: the SVG declares the encoding {printable(m.group(2))}; deformesh "
            "reads SVG in UTF-8, UTF-16, ASCII or Latin-1 (ISO-8859-1)"
        )


def _check_references(data: bytes, source: str) -> None:
    """Refuse ``<use>`` references that cycle, nest deeper than :data:`MAX_USE_DEPTH`,
    or expand the drawing past :data:`MAX_ELEMENTS` elements (references that
    multiply, level after level, would take svgelements hours): counted on the XML
    tree, before svgelements expands anything.  Files that are no XML pass through
    (svgelements names their problem)."""
    from xml.etree import ElementTree

    try:
        root = ElementTree.fromstring(data)
    except (ElementTree.ParseError, ValueError):
        return
    by_id = {e.get("id"): e for e in root.iter() if e.get("id")}
    done: dict[int, tuple[int, int]] = {}  # element -> (elements, reference depth)
    busy: set[int] = set()

    def href(e) -> str | None:
        ref = e.get("href") or e.get("{http://www.w3.org/1999/xlink}href")
        return ref[1:] if e.tag.rpartition("}")[2] == "use" and ref and ref[0] == "#" else None

    def size(e) -> tuple[int, int]:  # what e stands for, its references expanded
        if id(e) in done:
            return done[id(e)]
        if id(e) in busy:
            raise InputError(f"{source}: <use> references form a cycle (through {_tag(e)})")
        busy.add(id(e))
        n, depth = 1, 0
        for c in e:
            cn, cd = size(c)
            n, depth = n + cn, max(depth, cd)
        ref = href(e)
        if ref is not None and ref in by_id:
            rn, rd = size(by_id[ref])
            n, depth = n + rn, max(depth, rd + 1)
        if n > MAX_ELEMENTS:
            raise InputError(
                f"{source}: its <use> references expand to over {MAX_ELEMENTS:,} elements"
            )
        if depth > MAX_USE_DEPTH:
            raise InputError(f"{source}: <use> references nest deeper than {MAX_USE_DEPTH}")
        busy.discard(id(e))
        done[id(e)] = n, depth
        return n, depth

    try:
        size(root)
    except RecursionError:
        raise InputError(f"{source}: its elements nest too deep to read") from None


def _tag(e) -> str:
    name = e.tag.rpartition("}")[2]
    return f'<{name} id="{e.get("id")}">' if e.get("id") else f"<{name}>"


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _label(shape, k: int) -> str:
    tag = type(shape).__name__.lower()
    sid = shape.values.get("id") if hasattr(shape, "values") else None
    return f"{tag}#{sid}" if sid else f"{tag} {k + 1}"


def _filled(shape) -> bool:
    fill = shape.fill
    return fill is not None and fill.value is not None and fill.alpha != 0


def _stroked(shape) -> bool:
    s = shape.stroke
    width = shape.implicit_stroke_width
    return s is not None and s.value is not None and s.alpha != 0 and bool(width) and width > 0


#: SVG's stroke-linecap and stroke-linejoin as shapely's buffer styles.
_CAPS = {"butt": "flat", "round": "round", "square": "square"}
_JOINS = {"miter": "mitre", "miter-clip": "mitre", "arcs": "round", "round": "round",
          "bevel": "bevel"}  # fmt: skip


def _stroke_rings(shapes, tol: float, height: float, eps: float, source: str):
    """The region the shapes' strokes paint, as rings: each subpath widened by its
    stroke width (after transforms) with its caps and joins (``stroke-linecap``,
    ``stroke-linejoin``, ``stroke-miterlimit``; dashes are not drawn), round parts
    cut into chords within ``tol``, straight runs into pieces at most half the
    thinnest stroke wide, the strokes' union split into outlines and holes.
    Returns rings, labels and notes."""
    parts, widths = [], []
    for k, shape in enumerate(shapes):
        name = _label(shape, k)
        r = float(shape.implicit_stroke_width) / 2
        widths.append(2 * r)
        cap = _CAPS.get(str(shape.values.get("stroke-linecap", "butt")).strip().lower(), "flat")
        join = _JOINS.get(str(shape.values.get("stroke-linejoin", "miter")).strip().lower())
        try:
            limit = float(shape.values.get("stroke-miterlimit") or 4.0)
        except ValueError:
            limit = 4.0
        # chords of a round cap or join within tol of the arc: r (1 - cos(a / 2)) <= tol
        quad = math.ceil(math.pi / 2 / (2 * math.acos(max(-1.0, 1 - tol / r)))) if tol < r else 1
        style = {"quad_segs": int(min(256, max(1, quad))), "cap_style": cap,
                 "join_style": join or "mitre", "mitre_limit": max(1.0, limit)}  # fmt: skip
        for pts, closed in _subpaths(se.Path(shape), tol, f"{source}: {name}"):
            pts[:, 1] = height - pts[:, 1]
            check_scale(pts, source)
            pts = _drop_repeats(pts, eps)
            if closed and len(pts) >= 3:
                line = shapely.LinearRing(pts)
            elif len(pts) >= 2:
                line = shapely.LineString(pts)
            elif cap != "flat":  # a dot: a round or square cap on a zero-length subpath
                line = shapely.Point(pts[0])
            else:
                continue
            parts.append(line.buffer(r, **style))
    region = shapely.union_all(parts) if parts else shapely.Polygon()
    # the outline's points are ours, not the drawing's: straight runs get points every
    # half the thinnest stroke, so that long sides do not make slivers
    region = shapely.segmentize(region, min(widths) / 2) if widths else region
    polys = sorted(getattr(region, "geoms", [region]), key=lambda p: -p.area)
    polys = [p for p in polys if isinstance(p, shapely.Polygon) and not p.is_empty]
    if not polys:
        raise InputError(f"{source}: the strokes paint no area")
    rings, labels, merged = [], [], 0
    for i, poly in enumerate(polys):
        for j, ring in enumerate([poly.exterior, *poly.interiors]):
            xy = np.asarray(ring.coords)[:-1]
            kept = _merge_close(xy, tol)
            if _flat(kept):
                continue
            merged += len(xy) - len(kept)
            rings.append(kept)
            labels.append(f"stroke outline {i + 1}" + (f" hole {j}" if j else ""))
    holes = sum(1 for x in labels if " hole " in x)
    notes = [
        f"meshed the outline of {len(shapes)} stroked SVG shape(s) (stroke widths, caps and "
        f"joins as drawn, round parts within a chord tolerance of {tol:.3g}): "
        f"{len(rings) - holes} part(s), {holes} hole(s)"
    ]
    if merged:
        notes.append(f"merged {merged} outline point(s) closer than the tolerance {tol:.3g}")
    return rings, labels, notes


def _pick_shapes(svg, source: str, element_id: str | None, keep=_filled) -> list:
    """The shapes to mesh: those ``keep`` accepts (filled, or stroked with ``--stroke``),
    in the element ``element_id`` if given."""
    what = "filled" if keep is _filled else "stroked"
    if element_id is not None:
        found = svg.get_element_by_id(element_id)
        if found is None:
            ids = [e.id for e in svg.elements() if getattr(e, "id", None)]
            listing = ", ".join(ids[:10]) + (" ..." if len(ids) > 10 else "")
            raise OptionError(
                f"{source}: no element with id {element_id!r}"
                + (f"; ids: {listing}" if ids else "; the file has no ids")
            )
        if isinstance(found, se.Shape):
            return [found]
        shapes = [e for e in found.select() if isinstance(e, se.Shape) and keep(e)]
        if not shapes:
            raise InputError(f"{source}: element {element_id!r} holds no {what} shape")
        return shapes
    every = [e for e in svg.elements() if isinstance(e, se.Shape)]
    shapes = [e for e in every if keep(e)]
    if not shapes:
        hint = (
            "give --id to mesh one of them"
            if keep is _filled and not any(_stroked(e) for e in every)
            else "give --stroke to mesh their strokes' outline"
            if keep is _filled
            else "mesh the filled shapes without --stroke"
        )
        raise InputError(
            f"{source}: no {what} shape in the SVG ({len(every)} un{what} shape(s)); " + hint
        )
    return shapes


def _subpaths(path, tol: float, where: str = "") -> list[tuple[np.ndarray, bool]]:
    """Each subpath's points (the vertices, plus curve points within ``tol``) and
    whether it was closed (``Z``); path data not starting with a moveto is an
    :class:`InputError` naming ``where``."""
    out: list[list] = []
    closed: list[bool] = []
    cur: list | None = None
    for seg in path.segments():
        if isinstance(seg, se.Move):
            cur = [(seg.end.x, seg.end.y)]
            out.append(cur)
            closed.append(False)
            continue
        if cur is None:  # a path not starting with a move, or going on after a Z
            if seg.start is None:
                raise InputError(f"{where}: path data does not start with a moveto (M or m)")
            cur = [(seg.start.x, seg.start.y)]
            out.append(cur)
            closed.append(False)
        if isinstance(seg, se.Close):
            closed[-1] = True
            cur = None
            continue
        _check_points(seg, where)
        n = _pieces(seg, tol)
        if n > 1:
            t = np.arange(1, n) / n
            cur.extend(map(tuple, np.asarray(seg.npoint(t), dtype=float)))
        cur.append((seg.end.x, seg.end.y))
    return [(np.array(p, dtype=float), c) for p, c in zip(out, closed)]


def _check_points(seg, where: str) -> None:
    """Refuse a segment whose points (ends, control points, radii) reach beyond
    :data:`MAX_COORDINATE`: flattening it would overflow."""
    names = ("start", "end", "control", "control1", "control2")
    qs = [q for q in (getattr(seg, k, None) for k in names) if q is not None]
    values = [v for q in qs for v in (q.x, q.y)]
    if isinstance(seg, se.Arc):
        values += [float(seg.rx), float(seg.ry)]
    if not all(abs(float(v)) <= MAX_COORDINATE for v in values):
        raise InputError(
            f"{where}: a point of its path data is beyond {MAX_COORDINATE:g}: flattening "
            "would overflow in double precision; scale the drawing down"
        )


def _pieces(seg, tol: float) -> int:
    """How many equal parameter steps keep ``seg``'s chords within ``tol``."""

    def p(q):
        return np.array([q.x, q.y], dtype=float)

    if isinstance(seg, se.CubicBezier):
        a, b, c, d = p(seg.start), p(seg.control1), p(seg.control2), p(seg.end)
        second = 6 * max(np.linalg.norm(a - 2 * b + c), np.linalg.norm(b - 2 * c + d))
        span = 1.0
    elif isinstance(seg, se.QuadraticBezier):
        a, b, c = p(seg.start), p(seg.control), p(seg.end)
        second = 2 * np.linalg.norm(a - 2 * b + c)
        span = 1.0
    elif isinstance(seg, se.Arc):
        second = max(float(seg.rx), float(seg.ry))  # |C''| of (rx cos t, ry sin t)
        span = abs(float(seg.sweep))
    else:  # straight line
        return 1
    n = span * math.sqrt(second / (8 * tol)) if second > 0 else 1
    if not math.isfinite(n):  # (coordinates near overflow: refused once flattened)
        return 1
    return int(min(MAX_PIECES, max(1, math.ceil(n))))


def _merge_close(ring: np.ndarray, tol: float) -> np.ndarray:
    """Drop each point within ``tol`` of the last point kept before it (and closing
    points within ``tol`` of the first): every dropped point is within ``tol`` of a
    kept one, so a dense run (a bump drawn in steps shorter than ``tol``) keeps a
    point every ``tol`` and the outline moves by at most ``tol`` in all.  Only points
    closer than ``tol`` to their predecessor are walked one by one."""
    step = np.hypot(*np.diff(ring, axis=0).T)
    keep = np.concatenate([[True], step > tol])
    xy = ring.tolist()
    last = 0
    for i in np.flatnonzero(~keep).tolist():
        if keep[i - 1]:
            last = i - 1
        keep[i] = math.dist(xy[i], xy[last]) > tol
    out = ring[keep]
    while len(out) > 1 and np.hypot(*(out[-1] - out[0])) <= tol:
        out = out[:-1]
    return out


def _drop_repeats(ring: np.ndarray, eps: float) -> np.ndarray:
    """Drop points within ``eps`` of the previous one (zero-length segments, the closing one)."""
    step = np.hypot(*np.diff(ring, axis=0).T)
    out = ring[np.concatenate([[True], step > eps])]
    while len(out) > 1 and np.hypot(*(out[-1] - out[0])) <= eps:
        out = out[:-1]
    return out


def _flat(ring: np.ndarray) -> bool:
    """Fewer than 3 distinct points, or all on one line: no area, nothing to fill."""
    if len(np.unique(ring, axis=0)) < 3:
        return True
    d = ring - ring[0]
    far = d[np.argmax(np.hypot(d[:, 0], d[:, 1]))]
    span2 = float((far * far).sum())
    return bool(np.abs(d[:, 0] * far[1] - d[:, 1] * far[0]).max() <= 1e-13 * span2)


def _paint(shape) -> str:
    """What a filled shape paints with: its fill colour (alpha included) and opacity."""
    return f"{shape.fill} {shape.values.get('opacity', 1)}"


def _filled_region(rings, labels, element, evenodd, paints, shapes, eps, source):
    """The rings bounding the area the renderer fills, with their labels and notes.

    The linework of every ring is noded (split where rings touch or cross, their own
    or another's) and polygonized into faces; a face is filled when its winding
    number about some element's rings satisfies that element's fill rule (SVG 2,
    'fill-rule'); the region is the union of the filled faces.  Its boundary keeps
    every given point on it, adds each crossing point, and leaves out what lies
    inside the fill.  A boundary ring equal to a given subpath is that subpath as
    given (its start, direction and label): rings that meet nothing come out as
    they went in.  Faces filled by two elements of different paint make no single
    region: refused, naming both.
    """
    closed = [shapely.linestrings(np.vstack([r, r[:1]])) for r in rings]
    noded = shapely.get_parts(shapely.node(shapely.multilinestrings(closed)))
    faces = shapely.get_parts(shapely.polygonize(noded))
    inside = shapely.get_coordinates(shapely.point_on_surface(faces))
    face, owner, wind = _winding(rings, element, inside)
    odd = np.zeros(max(element) + 1, dtype=bool)  # each element's rule (its rings share it)
    odd[element] = evenodd
    fills = np.where(odd[owner], wind % 2 == 1, wind != 0)
    face, owner = face[fills], owner[fills]
    _check_one_paint(face, owner, faces, paints, shapes, source)
    filled = np.zeros(len(faces), dtype=bool)
    filled[face] = True
    region = shapely.coverage_union_all(faces[filled])
    out = [ring for poly in shapely.get_parts(region) for ring in [poly.exterior, *poly.interiors]]
    keys = [_points_key(r) for r in rings]
    given = {}
    for i, key in enumerate(keys):
        given.setdefault(key, i)
    whose = {}  # a given point -> the first ring holding it
    for i, r in enumerate(rings):
        for q in map(tuple, r.tolist()):
            whose.setdefault(q, i)
    result, notes, used = [], [], set()
    for ring in out:
        pts = shapely.get_coordinates(ring)[:-1]
        i = given.get(_points_key(pts))
        if i is not None:
            result.append((i, rings[i], labels[i]))
            used.add(i)
            continue
        pts = _without_near_crossings(pts, whose, eps)
        from_rings = sorted({whose[q] for q in map(tuple, pts.tolist()) if q in whose})
        first = from_rings[0] if from_rings else len(rings)
        used.update(from_rings)
        added = sum(1 for q in map(tuple, pts.tolist()) if q not in whose)
        names = [labels[j] for j in from_rings]
        label = names[0] if len(names) == 1 else f"{names[0]} merged with {len(names) - 1} more"
        notes.append(
            f"{' and '.join(names[:3]) + (' ...' if len(names) > 3 else '')} touch or cross: "
            f"meshed the boundary of what the renderer fills ({added} crossing point(s) added)"
        )
        result.append((first, pts, label))
    for i in sorted(set(range(len(rings))) - used):
        twin = given[keys[i]]
        if twin != i and twin in used:
            notes.append(f"dropped {labels[i]}: the same ring as {labels[twin]}")
            continue
        rule = "evenodd" if evenodd[i] else "nonzero"
        notes.append(f"dropped {labels[i]}: filled on both sides (fill rule {rule})")
    if not result:
        raise InputError(f"{source}: no filled area in the SVG (its subpaths fill nothing)")
    result.sort(key=lambda t: t[0])
    _check_no_pinch([r for _, r, _ in result], [lab for _, _, lab in result], source)
    return [r for _, r, _ in result], [lab for _, _, lab in result], notes


def _without_near_crossings(pts: np.ndarray, whose: dict, eps: float) -> np.ndarray:
    """A boundary ring with each pair of consecutive points closer than ``eps`` (the
    drawing's round-off: where rings touch, a crossing computed beside a given
    point, or two subpaths' copies of one point) made one: a given point is kept
    over a crossing, the first of two given ones."""
    given = np.array([tuple(q) in whose for q in pts.tolist()], dtype=bool)
    near = np.hypot(*(np.roll(pts, -1, axis=0) - pts).T) <= eps  # i and i + 1 one point
    drop = near & ~given
    drop |= np.roll(near & given, 1) & ~np.roll(drop, 1)  # (i + 1 after a kept given i)
    return pts[~drop]


def _check_no_pinch(rings, labels, source) -> None:
    """Refuse a filled area whose boundary meets itself at a point (two parts joined by
    one point, or a hole touching its outline): its rings must be apart."""
    pts = np.concatenate(rings)
    owner = np.repeat(np.arange(len(rings)), [len(r) for r in rings])
    _, first, count = np.unique(pts, axis=0, return_index=True, return_counts=True)
    if (count > 1).any():
        k = int(first[np.argmax(count > 1)])
        same = np.flatnonzero((pts == pts[k]).all(axis=1))
        a, b = labels[owner[same[0]]], labels[owner[same[1]]]
        who = f"{a} meets itself" if a == b else f"{a} and {b} meet"
        raise InputError(
            f"{source}: the filled area pinches to a point at ({pts[k][0]:.6g}, "
            f"{pts[k][1]:.6g}), where {who}; its boundary rings must be apart "
            "(one node there would join two parts of the mesh by a point)"
        )


def _points_key(ring: np.ndarray) -> bytes:
    """A ring's points as a set (the same ring from any start, either way round)."""
    return np.unique(np.asarray(ring, dtype=float), axis=0).tobytes() + len(ring).to_bytes(8)


def _winding(rings, element, points):
    """Winding numbers of ``points`` about each element's rings, as sparse entries.

    Returns (point, element, winding) for every pair with a nonzero count: the signed
    crossings of a ray from the point towards +x with the element's edges, upward
    edges counting +1 and downward -1 (half-open in y, so a vertex on the ray counts
    once).  The segments a ray meets come from an STRtree query, not all pairs.
    """
    a = np.concatenate(rings)
    b = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
    seg_el = np.repeat(np.asarray(element), [len(r) for r in rings])
    tree = shapely.STRtree(shapely.linestrings(np.stack([a, b], axis=1)))
    far = np.full(len(points), max(a[:, 0].max(), points[:, 0].max()) + 1.0)
    rays = shapely.linestrings(np.stack([points, np.column_stack([far, points[:, 1]])], axis=1))
    p, s = tree.query(rays)
    (x0, y0), (x1, y1) = a[s].T, b[s].T
    px, py = points[p].T
    side = (x1 - x0) * (py - y0) - (px - x0) * (y1 - y0)  # > 0: point left of a -> b
    up = (y0 <= py) & (y1 > py) & (side > 0)
    down = (y1 <= py) & (y0 > py) & (side < 0)
    w = up.astype(np.int64) - down.astype(np.int64)
    key = p.astype(np.int64) * (int(seg_el.max()) + 1) + seg_el[s]
    keys, inverse = np.unique(key, return_inverse=True)
    total = np.bincount(inverse, weights=w, minlength=len(keys)).astype(np.int64)
    keep = total != 0
    n_el = int(seg_el.max()) + 1
    return keys[keep] // n_el, keys[keep] % n_el, total[keep]


def _check_one_paint(face, owner, faces, paints, shapes, source) -> None:
    """Refuse faces filled by two elements of different paint (no one region), naming both."""
    order = np.lexsort((owner, face))
    face, owner = face[order], owner[order]
    same_face = face[1:] == face[:-1]
    differ = np.array([paints[i] != paints[j] for i, j in zip(owner[:-1], owner[1:])], dtype=bool)
    clash = np.flatnonzero(same_face & differ) if len(face) > 1 else np.array([], dtype=int)
    if len(clash):
        k = int(clash[0])
        i, j = int(owner[k]), int(owner[k + 1])
        x, y = shapely.get_coordinates(shapely.point_on_surface(faces[face[k]]))[0]
        raise InputError(
            f"{source}: {_label(shapes[i], i)} and {_label(shapes[j], j)} overlap near "
            f"({x:.6g}, {y:.6g}) with different fills; give --id to mesh one"
        )
