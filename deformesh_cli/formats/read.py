"""Reading a mesh file back (any format meshio reads): its 2D points, triangles and quads."""

from __future__ import annotations

import contextlib
import io
import re

import numpy as np

from ..contour import MAX_COORDINATE
from ..errors import InputError, ReadError
from ..files import existing_file


def read_meshio(path: str, fmt: str | None = None):
    """The ``meshio.Mesh`` of a mesh file, meshio's console output kept quiet and its
    failures one-line :class:`~deformesh_cli.errors.ReadError` messages."""
    import meshio

    existing_file(path)
    if (fmt or "").lower() == "vtu" or (fmt is None and path.lower().endswith(".vtu")):
        check_vtu_inflation(path)
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            return meshio.read(path, file_format=fmt)
    except SystemExit:
        raise ReadError(f"{path}: not a mesh file meshio can read") from None
    except meshio.ReadError as exc:
        raise ReadError(f"{path}: cannot read mesh: {exc}") from None
    except Exception as exc:  # parsers of malformed files raise anything
        raise ReadError(f"{path}: cannot read mesh: {type(exc).__name__}: {exc}") from None


#: The most bytes the compressed arrays of a .vtu file may inflate to (what meshio would
#: allocate for them): a file of a few MB must not take the machine's memory.
MAX_INFLATED = 2**31

_BINARY_ARRAY = re.compile(rb"<DataArray\b([^>]*)>\s*([A-Za-z0-9+/=]{16,})", re.S)
_APPENDED = re.compile(rb"<AppendedData[^>]*encoding=[\"']raw[\"'][^>]*>\s*_", re.S)
_OFFSET = re.compile(rb"<DataArray\b[^>]*\boffset=[\"'](\d+)[\"']", re.S)


def check_vtu_inflation(path: str) -> None:
    """Refuse a compressed .vtu whose arrays would inflate past :data:`MAX_INFLATED`,
    before meshio inflates them: each compressed array starts with its block count,
    block size and last block's size (VTK's layout), which give its inflated size
    without inflating it (inline base64 arrays, and raw appended data)."""
    import base64

    with open(path, "rb") as f:
        data = f.read()
    head = data[:4096]
    if b"compressor=" not in head:
        return
    wide = b'header_type="UInt64"' in head or b"header_type='UInt64'" in head
    size, code = (8, "<Q") if wide else (4, "<I")
    total = 0
    blob = None
    m = _APPENDED.search(data)
    if m is not None:
        blob = memoryview(data)[m.end() :]
    for offset in _OFFSET.findall(data) if blob is not None else []:
        at = int(offset)
        if at + 3 * size <= len(blob):
            total += _inflated(bytes(blob[at : at + 3 * size]), size, code)
    for attrs, text in _BINARY_ARRAY.findall(data):
        if b"binary" not in attrs:
            continue
        n = 4 * -(-3 * size // 3)  # (base64 characters of the three first numbers)
        try:
            total += _inflated(base64.b64decode(text[:n] + b"=" * (-n % 4))[: 3 * size], size, code)
        except ValueError:
            continue  # (meshio names what is wrong with it)
    if total > MAX_INFLATED:
        raise ReadError(
            f"{path}: its compressed arrays would inflate to {total:,} bytes, over "
            f"{MAX_INFLATED:,}; not read"
        )


def _inflated(header: bytes, size: int, code: str) -> int:
    """An array's inflated bytes from its compression header (blocks, block size, last
    block's size: 0 for a full one)."""
    import struct

    if len(header) < 3 * size:
        return 0
    blocks, block, last = struct.unpack(code[0] + 3 * code[1], header)
    return max(blocks - 1, 0) * block + (last or block) if blocks else 0


def read_mesh(path: str, fmt: str | None = None, *, point_data: bool = False, quads: bool = False):
    """A mesh file's 2D points and triangles (with ``quads``, then its quads; with
    ``point_data``, then its point data: a dict of arrays, one row a node).

    z must be 0 (the meshes are planar), and every coordinate finite and within
    :data:`~deformesh_cli.contour.MAX_COORDINATE`.  meshio prints and exits on some bad
    files; both become one-line :class:`~deformesh_cli.errors.ReadError` messages.
    Without ``quads``, a file with quads is an :class:`InputError` (the command works
    on triangles).
    """
    m = read_meshio(path, fmt)
    out = checked(m, path, quads=quads)
    if point_data:
        data = {k: np.asarray(v) for k, v in m.point_data.items() if len(v) == len(out[0])}
        return (*out, data)
    return out


def contour_nodes(point_data: dict, n: int, path: str) -> np.ndarray | None:
    """The nodes a deformesh mesh's ``contour_point`` array marks (>= 0) as a mask of
    ``n``, or None where the file has no such array; one that is not one finite number
    per node is an :class:`InputError` naming the file."""
    if "contour_point" not in point_data:
        return None
    v = np.asarray(point_data["contour_point"])
    if v.ndim == 2 and v.shape[1] == 1:
        v = v[:, 0]
    if v.shape != (n,) or v.dtype.kind not in "iuf" or not np.isfinite(v).all():
        raise InputError(
            f"{path}: its point data 'contour_point' is {v.shape} {v.dtype} values, not one "
            f"finite number for each of its {n} nodes (a deformesh mesh's numbers its "
            "contour points)"
        )
    return v >= 0


def checked(m, path: str, quads: bool = False):
    """A ``meshio.Mesh``'s 2D points and triangles (and with ``quads``, its quads),
    checked as :func:`read_mesh` says."""
    tri = [c.data for c in m.cells if c.type == "triangle"]
    quad = [c.data for c in m.cells if c.type == "quad"]
    if quad and not quads:
        k = sum(len(q) for q in quad)
        raise InputError(
            f"{path}: the mesh has {k:,} quads (boundary layers); this command works on "
            "triangles: write the mesh with --layer-cells tri"
        )
    if not tri and not quad:
        kinds = sorted({c.type for c in m.cells}) or ["none"]
        raise InputError(f"{path}: no triangles in the mesh (cells: {', '.join(kinds)})")
    pts = np.asarray(m.points, dtype=np.float64)
    if pts.shape[1] == 3:
        if np.any(pts[:, 2] != 0):
            k = int(np.argmax(pts[:, 2] != 0))
            raise InputError(
                f"{path}: node {k} has z = {pts[k, 2]:g}; only planar meshes (z = 0) are supported"
            )
        pts = pts[:, :2]
    bad = ~(np.abs(pts) <= MAX_COORDINATE).all(axis=1)  # (NaN fails the test too)
    if bad.any():
        k = int(np.argmax(bad))
        raise InputError(
            f"{path}: node {k} is at ({float(pts[k, 0]):g}, {float(pts[k, 1]):g}): "
            f"coordinates must be finite and within {MAX_COORDINATE:g}"
        )
    tri = np.concatenate(tri).astype(np.int64) if tri else np.zeros((0, 3), np.int64)
    quad = np.concatenate(quad).astype(np.int64) if quad else np.zeros((0, 4), np.int64)
    for cells, name in ((tri, "triangle"), (quad, "quad")):
        if len(cells) and (cells.min() < 0 or cells.max() >= len(pts)):
            raise InputError(f"{path}: a {name} refers to a node that does not exist")
    if quads:
        return np.ascontiguousarray(pts), tri, quad
    return np.ascontiguousarray(pts), tri
