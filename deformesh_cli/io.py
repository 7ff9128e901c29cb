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
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import DeformeshError, OptionError
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
    point_data = {"contour_point": np.where(np.arange(mesh.n_nodes) < mesh.n_contour,
                                            np.arange(mesh.n_nodes), -1).astype(np.int32)}
    return meshio.Mesh(
        pts,
        [("triangle", mesh.triangles.astype(np.int64)), ("line", mesh.lines.astype(np.int64))],
        point_data=point_data,
    )


#: Gmsh file versions offered by ``--msh-version`` -> meshio format name.
MSH_VERSIONS = {"2.2": "gmsh22", "4.1": "gmsh"}


def _write_gmsh(mesh: Mesh, path: str, version: str = "2.2") -> None:
    """Gmsh ASCII: triangles in ``domain``, one line block per boundary group."""
    import meshio

    g = groups(mesh)
    nt = len(mesh.triangles)
    line_tag = (mesh.line_group + 1).astype(np.int32)
    cells = [("triangle", mesh.triangles.astype(np.int64))]
    phys = [np.full(nt, g["domain"][0], np.int32)]
    for tag in np.unique(line_tag):
        cells.append(("line", mesh.lines[line_tag == tag].astype(np.int64)))
        phys.append(np.full(int((line_tag == tag).sum()), tag, np.int32))
    geom = [np.ones_like(phys[0])] + phys[1:]
    point_data = {}
    if version == "4.1":
        # 4.1 files place every node on a geometric entity: boundary nodes on
        # their boundary's curve (tag = group tag), the others on surface 1
        dim_tags = np.column_stack([np.full(mesh.n_nodes, 2), np.ones(mesh.n_nodes)])
        dim_tags[mesh.lines[:, 0]] = np.column_stack([np.ones(len(line_tag)), line_tag])
        point_data = {"gmsh:dim_tags": dim_tags.astype(np.int32)}
    m = meshio.Mesh(mesh.points, cells, point_data=point_data,
                    cell_data={"gmsh:physical": phys, "gmsh:geometrical": geom})
    m.field_data = {name: np.array([tag, dim]) for name, (tag, dim) in g.items()}
    meshio.write(path, m, file_format=MSH_VERSIONS[version], binary=False)


def _write_meshio(fmt: str, dim3: bool = False) -> Callable[[Mesh, str], None]:
    def write(mesh: Mesh, path: str) -> None:
        import meshio

        meshio.write(path, _meshio_mesh(mesh, dim3), file_format=fmt)

    return write


def _write_obj(mesh: Mesh, path: str) -> None:
    """Wavefront OBJ with z = 0, faces and the boundary as ``l`` lines (1-based)."""
    with open(path, "w", encoding="ascii", newline="\n") as f:
        f.write("# deformesh mesh: nodes 1..%d are the contour points\n" % mesh.n_contour)
        np.savetxt(f, mesh.points, fmt="v %.17g %.17g 0")
        np.savetxt(f, mesh.triangles + 1, fmt="f %d %d %d")
        np.savetxt(f, mesh.lines + 1, fmt="l %d %d")


#: extension -> (description, writer)
FORMATS: dict[str, tuple[str, Callable[[Mesh, str], None]]] = {
    "vtk": ("VTK legacy", _write_meshio("vtk", dim3=True)),
    "vtu": ("VTK XML unstructured grid", _write_meshio("vtu", dim3=True)),
    "msh": ("Gmsh 2.2 ASCII with named physical groups", _write_gmsh),
    "obj": ("Wavefront OBJ (z = 0)", _write_obj),
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
        with tempfile.TemporaryDirectory() as d:
            tmp = os.path.join(d, f"mesh.{fmt}")
            _quiet(writer, mesh, tmp)
            write_bytes(Path(tmp).read_bytes(), "-")
        return fmt
    with atomic_path(path) as tmp:
        try:
            _quiet(writer, mesh, tmp)
        except OSError as exc:
            raise DeformeshError(f"{path}: cannot write: {exc}") from None
        except Exception as exc:  # a writer's own error (meshio): one line, no traceback
            raise DeformeshError(f"{path}: cannot write {fmt}: {exc}") from None
    return fmt


def _quiet(writer, mesh, path):
    """Run a writer with meshio's console chatter kept off stdout."""
    with contextlib.redirect_stdout(io.StringIO()):
        writer(mesh, path)


def write_bytes(data: bytes, path: str) -> None:
    """Write bytes to a file atomically, or to stdout for ``-``."""
    if path == "-":
        out = sys.stdout.buffer
        out.write(data)
        out.flush()
        return
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)


def read_bytes(path: str) -> bytes:
    """Read a whole file, or all of stdin for ``-`` (works on non-seekable pipes)."""
    if path == "-":
        return sys.stdin.buffer.read()
    p = Path(path)
    if not p.exists():
        raise DeformeshError(f"{path}: no such file")
    if p.is_dir():
        raise DeformeshError(f"{path}: is a directory")
    try:
        return p.read_bytes()
    except OSError as exc:
        raise DeformeshError(f"{path}: cannot read: {exc.strerror}") from None


def read_mesh(path: str, fmt: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A mesh file's 2D points and triangles (any format meshio reads).

    z must be 0 (the meshes are planar).  meshio prints and exits on some bad
    files; both become one-line :class:`DeformeshError` messages.
    """
    import meshio

    p = Path(path)
    if not p.exists():
        raise DeformeshError(f"{path}: no such file")
    if p.is_dir():
        raise DeformeshError(f"{path}: is a directory")
    try:
        with contextlib.redirect_stdout(io.StringIO()):
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
            raise DeformeshError(f"{path}: node {k} has z = {pts[k, 2]:g}; only planar meshes "
                                 "(z = 0) are supported")
        pts = pts[:, :2]
    tri = np.concatenate(tri).astype(np.int64)
    if tri.min() < 0 or tri.max() >= len(pts):
        raise DeformeshError(f"{path}: a triangle refers to a node that does not exist")
    return np.ascontiguousarray(pts), tri
