"""Writing meshes and files.  The only module that imports meshio.

Every file is written atomically: to a temporary file in the target's folder,
then ``os.replace``; a failure leaves no partial file behind.  Output formats
come from :data:`FORMATS`, keyed by extension.
"""

from __future__ import annotations

import contextlib
import functools
import io
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .errors import DeformeshError, InputError, OptionError
from .mesh import Mesh


def groups(mesh: Mesh) -> dict[str, tuple[int, int]]:
    """Physical groups (name -> (tag, dimension)): the boundary groups 1, 2, ... then ``domain``."""
    out = {name: (k + 1, 1) for k, name in enumerate(mesh.groups)}
    out["domain"] = (len(mesh.groups) + 1, 2)
    return out


def _meshio_mesh(mesh: Mesh, dim3: bool = False):
    import meshio

    pts = mesh.points
    if dim3:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    point_data = {
        "contour_point": np.where(
            np.arange(mesh.n_nodes) < mesh.n_contour, np.arange(mesh.n_nodes), -1
        ).astype(np.int32),
        **mesh.point_data,
    }
    return meshio.Mesh(
        pts,
        [("triangle", mesh.triangles.astype(np.int64)), ("line", mesh.lines.astype(np.int64))],
        point_data=point_data,
    )


#: Gmsh file versions offered by ``--msh-version`` -> meshio format name.
MSH_VERSIONS = {"2.2": "gmsh22", "4.1": "gmsh"}


def _gmsh_blocks(mesh: Mesh) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """Element blocks as ``(meshio type, physical tags, geometrical tags, connectivity)``:
    the triangles (physical ``domain``, geometrical 1), then one block of lines per
    boundary group (physical = geometrical = the group's tag)."""
    nt = len(mesh.triangles)
    line_tag = (mesh.line_group + 1).astype(np.int64)
    blocks = [
        (
            "triangle",
            np.full(nt, groups(mesh)["domain"][0]),
            np.ones(nt, np.int64),
            mesh.triangles.astype(np.int64),
        )
    ]
    for tag in np.unique(line_tag):
        on = line_tag == tag
        blocks.append(("line", line_tag[on], line_tag[on], mesh.lines[on].astype(np.int64)))
    return blocks


def _write_gmsh(mesh: Mesh, path: str, version: str = "2.2") -> None:
    """Gmsh ASCII: triangles in ``domain``, one line block per boundary group.

    Version 2.2 by :func:`_write_gmsh22` (meshio's output, faster); 4.1 by meshio.
    """
    if version == "2.2":
        return _write_gmsh22(mesh, path)
    _write_gmsh_meshio(mesh, path, version)


def _write_gmsh_meshio(mesh: Mesh, path: str, version: str) -> None:
    import meshio

    blocks = _gmsh_blocks(mesh)
    point_data = {}
    if version == "4.1":
        # 4.1 files place every node on a geometric entity: boundary nodes on
        # their boundary's curve (tag = group tag), the others on surface 1
        line_tag = mesh.line_group + 1
        dim_tags = np.column_stack([np.full(mesh.n_nodes, 2), np.ones(mesh.n_nodes)])
        dim_tags[mesh.lines[:, 0]] = np.column_stack([np.ones(len(line_tag)), line_tag])
        point_data = {"gmsh:dim_tags": dim_tags.astype(np.int32)}
    m = meshio.Mesh(
        mesh.points,
        [(kind, conn) for kind, _, _, conn in blocks],
        point_data=point_data,
        cell_data={
            "gmsh:physical": [b[1].astype(np.int32) for b in blocks],
            "gmsh:geometrical": [b[2].astype(np.int32) for b in blocks],
        },
    )
    m.field_data = {name: np.array([tag, dim]) for name, (tag, dim) in groups(mesh).items()}
    meshio.write(path, m, file_format=MSH_VERSIONS[version], binary=False)


def _rows(fmt: str, table: np.ndarray) -> str:
    """``fmt`` (one row's %-format, ending in a newline) applied to every row of ``table``.

    One %-operation over the whole table: meshio's ASCII writer formats row by
    row in Python (measured at a million triangles: 12.3 s for the file through
    meshio, 2.1 s this way).
    """
    if len(table) == 0:
        return ""
    return (fmt * len(table)) % tuple(table.ravel().tolist())


_GMSH_TYPE = {"triangle": 2, "line": 1}


def _write_gmsh22(mesh: Mesh, path: str) -> None:
    """Gmsh 2.2 ASCII, byte for byte what meshio writes for the same blocks
    (:func:`_write_gmsh_meshio`, tested), only faster."""
    names = sorted((dim, tag, name) for name, (tag, dim) in groups(mesh).items())
    blocks = _gmsh_blocks(mesh)
    n = mesh.n_nodes
    parts = ["$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"]
    if names:
        parts.append(f"$PhysicalNames\n{len(names)}\n")
        parts += [f'{dim} {tag} "{name}"\n' for dim, tag, name in names]
        parts.append("$EndPhysicalNames\n")
    nodes = np.empty((n, 4), dtype=object)
    nodes[:, 0] = np.arange(1, n + 1)
    nodes[:, 1:3] = mesh.points
    nodes[:, 3] = 0.0
    parts += [f"$Nodes\n{n}\n", _rows("%d %.16e %.16e %.16e\n", nodes), "$EndNodes\n"]
    parts.append(f"$Elements\n{sum(len(b[3]) for b in blocks)}\n")
    first = 1
    for kind, phys, geom, conn in blocks:
        k = len(conn)
        table = np.column_stack([np.arange(first, first + k), phys, geom, conn + 1])
        parts.append(_rows(f"%d {_GMSH_TYPE[kind]} 2" + " %d" * (2 + conn.shape[1]) + "\n", table))
        first += k
    parts.append("$EndElements\n")
    with open(path, "w", encoding="ascii", newline="\n") as fh:
        fh.writelines(parts)


def _write_meshio(fmt: str, dim3: bool = False) -> Callable[[Mesh, str], None]:
    def write(mesh: Mesh, path: str) -> None:
        import meshio

        meshio.write(path, _meshio_mesh(mesh, dim3), file_format=fmt)

    return write


#: The second line of our .vtk files (a free-text title in the legacy format).
VTK_TITLE = "deformesh mesh: point k < number of contour points is contour point k"


def _write_vtk(mesh: Mesh, path: str) -> None:
    """VTK legacy 5.1, binary (big-endian): what meshio writes for the same mesh
    (triangles, then the boundary lines; point data ``contour_point``), bytes for
    bytes but the title line (tested), without importing meshio (0.15 s)."""
    n, tri, lines = mesh.n_nodes, mesh.triangles, mesh.lines
    nt, nl = len(tri), len(lines)
    pts = np.zeros((n, 3), dtype=">f8")
    pts[:, :2] = mesh.points
    offsets = np.concatenate(
        [np.arange(0, 3 * nt + 1, 3), 3 * nt + np.arange(2, 2 * nl + 1, 2)]
    ).astype(">i8")
    conn = np.concatenate([tri.ravel(), lines.ravel()]).astype(">i8")
    types = np.repeat(np.array([5, 3], dtype=">i4"), [nt, nl])  # VTK_TRIANGLE, VTK_LINE
    contour_point = np.where(np.arange(n) < mesh.n_contour, np.arange(n), -1).astype(">i4")
    fields = [(f"contour_point 1 {n} vtktypeint32\n".encode(), contour_point)]
    for name, data in mesh.point_data.items():  # as meshio writes them: floats as double
        data = np.asarray(data, dtype=">f8")
        k = 1 if data.ndim == 1 else data.shape[1]
        fields.append((f"{name} {k} {n} double\n".encode(), data))
    with open(path, "wb") as f:
        f.write(
            f"# vtk DataFile Version 5.1\n{VTK_TITLE}\nBINARY\n"
            f"DATASET UNSTRUCTURED_GRID\nPOINTS {n} double\n".encode()
        )
        for head, data in (
            (b"", pts),
            (f"CELLS {nt + nl + 1} {3 * nt + 2 * nl}\nOFFSETS vtktypeint64\n".encode(), offsets),
            (b"CONNECTIVITY vtktypeint64\n", conn),
            (f"CELL_TYPES {nt + nl}\n".encode(), types),
            (
                f"POINT_DATA {n}\nFIELD FieldData {len(fields)}\n".encode() + fields[0][0],
                contour_point,
            ),
            *fields[1:],
        ):
            f.write(head)
            f.write(data.tobytes())
            f.write(b"\n")


def _write_obj(mesh: Mesh, path: str) -> None:
    """Wavefront OBJ with z = 0, faces and the boundary as ``l`` lines (1-based)."""
    with open(path, "w", encoding="ascii", newline="\n") as f:
        f.write(f"# deformesh mesh: nodes 1..{mesh.n_contour} are the contour points\n")
        np.savetxt(f, mesh.points, fmt="v %.17g %.17g 0")
        np.savetxt(f, mesh.triangles + 1, fmt="f %d %d %d")
        np.savetxt(f, mesh.lines + 1, fmt="l %d %d")


def _write_ply(mesh: Mesh, path: str) -> None:
    """Binary little-endian PLY: vertices (z = 0) and triangular faces.

    Our own writer: meshio's stamps the time into the header and writes the
    boundary lines as two-vertex faces.  PLY has no boundary markers; the
    boundary is the edges used by one face (``edge`` elements would be standard
    but meshio's reader refuses them).
    """
    n, t = mesh.n_nodes, len(mesh.triangles)
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment deformesh mesh: vertices 0..{mesh.n_contour - 1} are the contour points\n"
        f"element vertex {n}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {t}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    v = np.zeros((n, 3), "<f8")
    v[:, :2] = mesh.points
    f = np.zeros(t, dtype=[("k", "u1"), ("v", "<i4", 3)])
    f["k"], f["v"] = 3, mesh.triangles
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(v.tobytes())
        out.write(f.tobytes())


def _write_su2(mesh: Mesh, path: str) -> None:
    """SU2 native mesh: triangles (VTK type 5), nodes, one MARKER_TAG per boundary group.

    Our own writer: meshio's su2 writer fails on boundary line cells.
    """
    with open(path, "w", encoding="ascii", newline="\n") as f:
        f.write(f"% deformesh mesh: points 0..{mesh.n_contour - 1} are the contour points\n")
        f.write(f"NDIME= 2\nNELEM= {len(mesh.triangles)}\n")
        tri = np.column_stack(
            [np.full(len(mesh.triangles), 5), mesh.triangles, np.arange(len(mesh.triangles))]
        )
        np.savetxt(f, tri, fmt="%d")
        f.write(f"NPOIN= {mesh.n_nodes}\n")
        for k, (x, y) in enumerate(mesh.points.tolist()):
            f.write(f"{x!r} {y!r} {k}\n")
        f.write(f"NMARK= {len(np.unique(mesh.line_group))}\n")
        for g, name in enumerate(mesh.groups):
            lines = mesh.lines[mesh.line_group == g]
            if len(lines) == 0:
                continue
            f.write(f"MARKER_TAG= {name}\nMARKER_ELEMS= {len(lines)}\n")
            np.savetxt(f, np.column_stack([np.full(len(lines), 3), lines]), fmt="%d")


def _write_xdmf(mesh: Mesh, path: str) -> None:
    """XDMF 3 + HDF5 sidecar (meshio; needs h5py): triangles and boundary lines, ``group`` tags.

    The tags are those of the .msh physical groups (boundaries 1.., domain last).
    The sidecar is named after ``path`` (``mesh.xdmf`` -> ``mesh.h5``).
    """
    try:
        import h5py  # noqa: F401
    except ImportError:
        raise DeformeshError(
            f"{path}: writing .xdmf needs h5py: pip install 'deformesh[all]'"
        ) from None
    import meshio

    g = groups(mesh)
    pts = np.column_stack([mesh.points, np.zeros(mesh.n_nodes)])
    m = meshio.Mesh(
        pts,
        [("triangle", mesh.triangles.astype(np.int64)), ("line", mesh.lines.astype(np.int64))],
        point_data={
            "contour_point": np.where(
                np.arange(mesh.n_nodes) < mesh.n_contour, np.arange(mesh.n_nodes), -1
            ).astype(np.int32),
            **mesh.point_data,
        },
        cell_data={
            "group": [
                np.full(len(mesh.triangles), g["domain"][0], np.int32),
                (mesh.line_group + 1).astype(np.int32),
            ]
        },
    )
    meshio.write(path, m, file_format="xdmf")


#: Formats that write a mesh's ``point_data`` (``contour_point`` and the rest).
POINT_DATA_FORMATS = ("vtk", "vtu", "xdmf")

#: Formats that write a second file next to the first: extension -> sidecar extension.
SIDECARS = {"xdmf": ".h5"}

#: extension -> (description, writer)
FORMATS: dict[str, tuple[str, Callable[[Mesh, str], None]]] = {
    "vtk": ("VTK legacy 5.1, binary", _write_vtk),
    "vtu": ("VTK XML unstructured grid", _write_meshio("vtu", dim3=True)),
    "msh": ("Gmsh 2.2 ASCII with named physical groups", _write_gmsh),
    "obj": ("Wavefront OBJ (z = 0)", _write_obj),
    "ply": ("PLY binary (z = 0), triangles only", _write_ply),
    "su2": ("SU2 native, one MARKER_TAG per boundary", _write_su2),
    "xdmf": ("XDMF 3 with an HDF5 sidecar (.h5; needs h5py)", _write_xdmf),
}


def format_for(path: str, fmt: str | None) -> str:
    """The output format: ``fmt`` if given, else the file's extension."""
    if fmt is None:
        if path == "-":
            raise OptionError("writing a mesh to stdout needs --format")
        fmt = Path(path).suffix.lower().lstrip(".")
    fmt = fmt.lower().lstrip(".")
    if fmt not in FORMATS:
        raise OptionError(
            f"unknown output format {fmt!r} for {path}; known: {', '.join(sorted(FORMATS))}"
        )
    return fmt


def check_folder(path: str) -> Path:
    """The folder ``path`` would be written in; raise if it does not exist."""
    folder = Path(path).parent
    if not folder.is_dir():
        raise DeformeshError(f"{path}: cannot write: folder {folder} does not exist")
    return folder


@contextlib.contextmanager
def atomic_path(path: str):
    """Yield a temporary path next to ``path``; move it into place on success only."""
    target = Path(path)
    folder = check_folder(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise DeformeshError(f"{path}: cannot write: {exc.strerror}") from None
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_mesh(mesh: Mesh, path: str, fmt: str | None = None, msh_version: str = "2.2") -> str:
    """Write ``mesh`` to ``path`` (``-`` is stdout) in ``fmt`` or by extension."""
    fmt = format_for(path, fmt)
    writer = FORMATS[fmt][1]
    if fmt == "msh":
        if msh_version not in MSH_VERSIONS:
            raise OptionError(f"--msh-version must be one of {', '.join(MSH_VERSIONS)}")
        writer = functools.partial(_write_gmsh, version=msh_version)
    if path == "-":
        if fmt in SIDECARS:
            raise OptionError(f"{fmt} writes two files; it cannot go to stdout")
        with tempfile.TemporaryDirectory() as d:
            tmp = os.path.join(d, f"mesh.{fmt}")
            _quiet(writer, mesh, tmp)
            write_bytes(Path(tmp).read_bytes(), "-")
        return fmt
    if fmt in SIDECARS:
        _write_with_sidecar(mesh, path, writer, SIDECARS[fmt])
        return fmt
    with atomic_path(path) as tmp:
        try:
            _quiet(writer, mesh, tmp)
        except OSError as exc:
            raise DeformeshError(f"{path}: cannot write: {exc}") from None
        except Exception as exc:  # a writer's own error (meshio): one line, no traceback
            raise DeformeshError(f"{path}: cannot write {fmt}: {exc}") from None
    return fmt


def pvd_bytes(entries: list[tuple[float, str]]) -> bytes:
    """A ParaView collection (``.pvd``): a time series of ``(time, file name)``, the
    names relative to the .pvd's folder."""
    from xml.sax.saxutils import quoteattr

    rows = "".join(
        f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(name)}/>\n'
        for t, name in entries
    )
    return (
        '<?xml version="1.0"?>\n'
        '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
        f"  <Collection>\n{rows}  </Collection>\n</VTKFile>\n"
    ).encode()


def mesh_files(
    mesh: Mesh, name: str, fmt: str, msh_version: str = "2.2"
) -> list[tuple[str, bytes]]:
    """The files ``write_mesh(mesh, name)`` would write, as ``[(file name, bytes)]`` in the
    order to write them (a sidecar before the file that refers to it)."""
    fmt = format_for(name, fmt)
    with tempfile.TemporaryDirectory() as d:
        write_mesh(mesh, os.path.join(d, name), fmt, msh_version)
        main = Path(d) / name
        others = sorted(p for p in Path(d).iterdir() if p != main)
        return [(p.name, p.read_bytes()) for p in others + [main]]


def _write_with_sidecar(mesh: Mesh, path: str, writer, ext: str) -> None:
    """Write both files in a temporary folder next to ``path``, then move them into place."""
    target = Path(path)
    folder = check_folder(path)
    side = target.with_suffix(ext)
    with tempfile.TemporaryDirectory(prefix=f".{target.name}.", dir=folder) as d:
        tmp = Path(d) / target.name
        try:
            _quiet(writer, mesh, str(tmp))
        except DeformeshError:
            raise
        except Exception as exc:
            raise DeformeshError(f"{path}: cannot write {target.suffix[1:]}: {exc}") from None
        for p in (tmp.with_suffix(ext), tmp):
            os.chmod(p, 0o644)
        os.replace(tmp.with_suffix(ext), side)
        os.replace(tmp, target)


def _quiet(writer, mesh, path):
    """Run a writer with meshio's console chatter kept off stdout and stderr."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        writer(mesh, path)


def write_bytes(data: bytes, path: str) -> None:
    """Write bytes to a file atomically, or to stdout for ``-``."""
    if path == "-":
        out = sys.stdout.buffer
        out.write(data)
        out.flush()
        return
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        f.write(data)


def _existing_file(path: str) -> Path:
    """``path`` as a Path, or an :class:`InputError` if it is missing or a folder."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{path}: no such file")
    if p.is_dir():
        raise InputError(f"{path}: is a directory")
    return p


def read_bytes(path: str) -> bytes:
    """Read a whole file, or all of stdin for ``-`` (works on non-seekable pipes)."""
    if path == "-":
        return sys.stdin.buffer.read()
    p = _existing_file(path)
    try:
        return p.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None


def read_mesh(path: str, fmt: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A mesh file's 2D points and triangles (any format meshio reads).

    z must be 0 (the meshes are planar).  meshio prints and exits on some bad
    files; both become one-line :class:`DeformeshError` messages.
    """
    import meshio

    _existing_file(path)
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            m = meshio.read(path, file_format=fmt)
    except SystemExit:
        raise DeformeshError(f"{path}: not a mesh file meshio can read") from None
    except meshio.ReadError as exc:
        raise DeformeshError(f"{path}: cannot read mesh: {exc}") from None
    except Exception as exc:  # parsers of malformed files raise anything
        raise DeformeshError(f"{path}: cannot read mesh: {type(exc).__name__}: {exc}") from None
    tri = [c.data for c in m.cells if c.type == "triangle"]
    if not tri:
        kinds = sorted({c.type for c in m.cells}) or ["none"]
        raise DeformeshError(f"{path}: no triangles in the mesh (cells: {', '.join(kinds)})")
    pts = np.asarray(m.points, dtype=np.float64)
    if pts.shape[1] == 3:
        if np.any(pts[:, 2] != 0):
            k = int(np.argmax(pts[:, 2] != 0))
            raise DeformeshError(
                f"{path}: node {k} has z = {pts[k, 2]:g}; only planar meshes (z = 0) are supported"
            )
        pts = pts[:, :2]
    tri = np.concatenate(tri).astype(np.int64)
    if tri.min() < 0 or tri.max() >= len(pts):
        raise DeformeshError(f"{path}: a triangle refers to a node that does not exist")
    return np.ascontiguousarray(pts), tri
