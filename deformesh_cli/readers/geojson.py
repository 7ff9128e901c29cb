"""GeoJSON (RFC 7946) contours: the areas of Polygon and MultiPolygon geometries.

A file may hold a bare geometry, a Feature, a FeatureCollection or a
GeometryCollection; every Polygon's outer ring and holes become rings of the
contour, every MultiPolygon's polygons separate parts.  Rings are closed in
GeoJSON (the last position repeats the first): the repeat is dropped.  A third
coordinate (altitude) is ignored.  Other geometries (points, lines) cannot be
meshed and are refused by name and place.  Coordinates are taken as they are
(longitude, latitude for geographic data): project them first for a mesh in
metres.
"""

from __future__ import annotations

import json

import numpy as np

from ..contour import Contour, make_contour, ring_nesting
from ..errors import InputError
from ..files import parse_json

#: GeoJSON nests geometries at most this deep (a GeometryCollection in a Feature ...).
MAX_DEPTH = 32

#: The collections: their list of members, and how messages name one.
_MEMBERS = {
    "FeatureCollection": ("features", "feature"),
    "GeometryCollection": ("geometries", "geometry"),
}


def read_geojson(data: bytes, source: str) -> Contour:
    """A GeoJSON file's bytes as a :class:`Contour` (see the module docstring)."""
    try:
        doc = parse_json(data.decode("utf-8-sig"))
    except UnicodeDecodeError as exc:
        raise InputError(f"{source}: not UTF-8 text (byte {exc.start}); expected GeoJSON") from None
    except json.JSONDecodeError as exc:
        raise InputError(
            f"{source}: line {exc.lineno}, column {exc.colno}: not valid JSON ({exc.msg})"
        ) from None
    except RecursionError:
        raise InputError(f"{source}: JSON nested too deep to be GeoJSON") from None
    rings: list[np.ndarray] = []
    labels: list[str] = []
    _collect(doc, "", source, rings, labels, 0)
    if not rings:
        raise InputError(f"{source}: no Polygon or MultiPolygon in the GeoJSON")
    starts = np.cumsum([0] + [len(r) for r in rings])[:-1]
    holes = [" hole " in label for label in labels]  # (RFC 7946: holes run clockwise)
    c = make_contour(
        np.concatenate(rings),
        None,
        source,
        ring_starts=starts,
        ring_labels=labels,
        clockwise_by_convention=holes,
    )
    _check_roles(c, rings, labels, source)
    note = f"read {len(rings)} ring(s) from GeoJSON"
    return Contour(
        c.points,
        c.lines,
        source,
        notes=(note, *c.notes),
        starts=c.starts,
        ring_clockwise=c.ring_clockwise,
        depth=c.depth,
        ring_labels=c.ring_labels,
    )


def _collect(obj, where: str, source: str, rings: list, labels: list, depth: int) -> None:
    """Append the rings of the GeoJSON object ``obj`` (named ``where`` in messages)."""
    if depth > MAX_DEPTH:
        raise InputError(f"{source}: {where or 'the document'}: GeoJSON nested too deep")
    if not isinstance(obj, dict) or not isinstance(obj.get("type"), str):
        raise InputError(f"{source}: {where or 'the document'}: not a GeoJSON object (no 'type')")
    kind = obj["type"]
    at = f"{where} " if where else ""
    if kind in _MEMBERS:
        key, child = _MEMBERS[kind]
        members = obj.get(key)
        if not isinstance(members, list):
            raise InputError(f"{source}: {at}{kind} has no {key!r} list")
        for k, member in enumerate(members, start=1):
            _collect(member, f"{at}{child} {k}".strip(), source, rings, labels, depth + 1)
    elif kind == "Feature":
        geometry = obj.get("geometry")
        if geometry is not None:  # (a feature without a geometry has no area)
            _collect(geometry, where or "feature", source, rings, labels, depth + 1)
    elif kind == "Polygon":
        _polygon(obj.get("coordinates"), where or "polygon", source, rings, labels)
    elif kind == "MultiPolygon":
        polys = obj.get("coordinates")
        if not isinstance(polys, list):
            raise InputError(f"{source}: {at}MultiPolygon has no coordinates list")
        for k, poly in enumerate(polys, start=1):
            _polygon(poly, f"{at}polygon {k}".strip(), source, rings, labels)
    elif kind in ("Point", "MultiPoint", "LineString", "MultiLineString"):
        raise InputError(
            f"{source}: {where or 'the document'} is a {kind}; only Polygon and "
            "MultiPolygon areas can be meshed"
        )
    else:
        raise InputError(f"{source}: {where or 'the document'}: unknown GeoJSON type {kind!r}")


def _polygon(coords, where: str, source: str, rings: list, labels: list) -> None:
    """Append one Polygon's rings: its outer ring, then its holes."""
    if not isinstance(coords, list) or not coords:
        raise InputError(f"{source}: {where}: a Polygon needs a list of rings")
    for k, ring in enumerate(coords):
        name = f"{where} outer ring" if k == 0 else f"{where} hole {k}"
        if not isinstance(ring, list) or not all(isinstance(p, list) for p in ring):
            raise InputError(f"{source}: {name}: a ring is a list of positions")
        if any(len(p) < 2 for p in ring):
            bad = next(j for j, p in enumerate(ring) if len(p) < 2)
            raise InputError(f"{source}: {name}: position {bad} has fewer than 2 coordinates")
        try:
            p = np.array([q[:2] for q in ring], dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"{source}: {name}: a position is not two numbers") from None
        if not np.isfinite(p).all():
            bad = int(np.argmax(~np.isfinite(p).all(axis=1)))
            raise InputError(f"{source}: {name}: position {bad} is not finite")
        if len(p) > 1 and np.array_equal(p[0], p[-1]):
            p = p[:-1]  # (GeoJSON closes every ring: no note for the repeat)
        rings.append(p)
        labels.append(name)


def _check_roles(c: Contour, rings: list, labels: list, source: str) -> None:
    """Refuse rings whose nesting is not their roles' (RFC 7946: a Polygon is its outer
    ring minus its holes, a MultiPolygon or a set of features the union of its
    polygons).  The contour's region is the rings' nesting (even-odd), which is that
    union exactly when every hole lies directly in its own outer ring and every outer
    ring lies in no other ring but, directly, a hole of another polygon."""
    if len(rings) == 1:
        return
    _, parent = ring_nesting([c.points[c.starts[r] : c.starts[r + 1]] for r in range(len(rings))])
    outer = np.array([label.endswith("outer ring") for label in labels])
    own = np.maximum.accumulate(np.where(outer, np.arange(len(rings)), -1))  # each one's shell
    for r in range(len(rings)):
        up = int(parent[r])
        x, y = c.points[c.starts[r]]
        at = f"(its first position ({x:.6g}, {y:.6g}))"
        if not outer[r] and up != own[r]:
            where = "outside every ring" if up < 0 else f"inside {labels[up]}"
            raise InputError(
                f"{source}: {labels[r]} lies {where} {at}, not directly in "
                f"{labels[own[r]]}: a hole lies in its own outer ring and in none of its "
                "other holes (RFC 7946)"
            )
        if outer[r] and up >= 0 and outer[up]:
            raise InputError(
                f"{source}: {labels[r]} lies inside {labels[up]} {at}: the polygons "
                "overlap; merge them into one polygon for the region that is their union"
            )
