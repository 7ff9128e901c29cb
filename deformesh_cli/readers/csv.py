"""CSV contours: text -> validated :class:`~deformesh_cli.contour.Contour`."""

from __future__ import annotations

import math
import re

import numpy as np

from ..contour import Contour, make_contour
from ..errors import InputError, OptionError

_DELIMITERS = (",", ";", "\t")


_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^[+-]?(nan|inf|infinity)$", re.I)


def _fields(n: int) -> str:
    return f"{n} field" if n == 1 else f"{n} fields"


def _split(line: str, delim: str | None) -> list[str]:
    if delim is None:
        return line.split()
    fields = line.split(delim)
    return fields if all(f == f.strip() for f in fields) else [f.strip() for f in fields]


def _whole(text: str) -> int | None:
    """The integer ``text`` writes, if it is a whole number up to 2**53, else None."""
    try:
        v = float(text)
    except ValueError:
        return None
    return int(v) if math.isfinite(v) and v == int(v) and abs(v) <= 2**53 else None


def read_csv(data: bytes, name: str, decimal: str = ".") -> Contour:
    """A CSV file's bytes (UTF-8, an optional BOM) as a :class:`Contour` (:func:`parse_csv`)."""
    if b"\x00" in data[:4096]:
        raise InputError(f"{name}: binary file, expected CSV text with x,y columns")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise InputError(
            f"{name}: line {line}: not UTF-8 text (byte {exc.start}); expected CSV with x,y columns"
        ) from None
    return parse_csv(text, name, decimal)


def parse_csv(text: str, source: str = "<contour>", decimal: str = ".") -> Contour:
    """Parse CSV text into a validated :class:`Contour`.

    Accepts an optional header naming ``x``, ``y`` (and ``ring``), ``#``
    comments, blank lines, and ``,`` ``;`` tab or whitespace delimiters (the
    first data line decides).  With ``decimal=","`` numbers are written
    ``1,5`` and the delimiter is ``;`` tab or whitespace.  Raises
    :class:`InputError` naming the line.
    """
    if decimal not in (".", ","):
        raise OptionError(f"--decimal must be '.' or ',', got {decimal!r}")
    delimiters = _DELIMITERS if decimal == "." else (";", "\t")
    text = text.removeprefix("\ufeff")
    rows: list[tuple[int, list[str]]] = []
    delim: str | None = None
    decided = False
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if not decided:
            delim = next((d for d in delimiters if d in line), None)
            decided = True
        fields = _split(line, delim)
        if decimal == ",":
            fields = [f.replace(",", ".") for f in fields]
        rows.append((lineno, fields))
    if not rows:
        raise InputError(f"{source}: empty: no points (expected CSV with x,y columns)")

    cols = {"x": 0, "y": 1}
    ring_col: int | None = None
    first_line, first = rows[0]
    if not all(_NUMBER.match(f) for f in first if f):
        names = [f.strip().strip('"').strip("'").lower() for f in first]
        if "x" not in names or "y" not in names:
            raise InputError(
                f"{source}: line {first_line}: header {','.join(first)!r} must name columns x and y"
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
            raise InputError(f"{source}: line {first_line}: expected 2 columns x,y, got {ncols}")
        if ncols >= 3:
            ring_col = 2

    fields = [f for _, f in rows]
    lines = np.array([lineno for lineno, _ in rows], dtype=np.int64)
    # the first problem in the file's order (a row's fields counted, then its x, y, ring)
    rc = next((r for r, f in enumerate(fields) if len(f) != ncols), len(fields))
    head = fields[:rc]  # (rows whose fields can be read)
    columns = [[f[cols[key]] for f in head] for key in ("x", "y")]
    rn = None
    if not all(all(map(_NUMBER.match, column)) for column in columns):
        rn, key, bad_value = min(
            (r, key, f)
            for key, column in zip("xy", columns)
            for r, f in enumerate(column)
            if not _NUMBER.match(f)
        )  # (the first row with one, x before y)
    whole = [_whole(f[ring_col]) for f in head] if ring_col is not None else []
    rr = next((r for r, v in enumerate(whole) if v is None), None)
    if rn is not None and (rr is None or rn <= rr):
        hint = ""  # (a number written with a decimal comma: say how to read it)
        if decimal == "." and _NUMBER.match(bad_value.replace(",", ".", 1)):
            hint = " (for decimal commas give --decimal ,)"
        raise InputError(
            f"{source}: line {lines[rn]}: {key} value {bad_value!r} is not a number{hint}"
        )
    if rr is not None:
        # a whole number that a double holds exactly (1.5, 1e19, inf are refused: read
        # as an integer they would silently name another ring)
        raise InputError(
            f"{source}: line {lines[rr]}: ring value {head[rr][ring_col]!r} is not an "
            "integer (ring ids are whole numbers up to 2**53)"
        )
    if rc < len(fields):  # a stray field (a thousands separator?) is never dropped
        raise InputError(
            f"{source}: line {lines[rc]}: {_fields(len(fields[rc]))}, but line {first_line} "
            f"has {ncols}; every row must have the same number of fields"
        )
    xy = np.array([[float(v) for v in column] for column in columns]).T.reshape(-1, 2)
    rings = np.array(whole, dtype=np.int64) if whole else np.zeros(len(rows), dtype=np.int64)
    bad = ~np.isfinite(xy).all(axis=1)
    if bad.any():
        r = int(np.argmax(bad))
        raise InputError(
            f"{source}: line {lines[r]}: point {r} has a non-finite coordinate "
            f"({xy[r, 0]}, {xy[r, 1]})"
        )
    change = np.flatnonzero(rings[1:] != rings[:-1]) + 1
    seen = rings[np.concatenate([[0], change])]
    if len(np.unique(seen)) != len(seen):
        dup = int(seen[np.flatnonzero([v in seen[:i] for i, v in enumerate(seen)])[0]])
        r = int(change[np.flatnonzero(seen[1:] == dup)[0]])
        raise InputError(
            f"{source}: line {lines[r]}: ring {dup} starts again after another ring; "
            "give each ring's points together"
        )
    return make_contour(xy, lines, source, ring_starts=np.concatenate([[0], change]))
