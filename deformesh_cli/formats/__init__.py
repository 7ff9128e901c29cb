"""Mesh output formats, one module each, behind the registry :data:`FORMATS`.

Adding a format is a module with a ``write(mesh, path, version)`` function
and a :class:`~.format.Format` named ``FORMAT``, and its line in
:data:`_MODULES`.  :func:`write_mesh` is the one way a mesh reaches a file:
atomically (a failure leaves no file), with a format's sidecar moved into
place with it, meshio's console chatter kept quiet, and any writer error
turned into one :class:`~deformesh_cli.errors.WriteError` line.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import tempfile
from pathlib import Path

from ..errors import DeformeshError, OptionError, WriteError
from ..files import atomic_path, check_folder, output_target, write_bytes
from ..mesh import Mesh
from . import gmsh, obj, ply, su2, vtk, vtu, xdmf
from .format import Format
from .pvd import pvd_bytes
from .read import read_mesh

_MODULES = (vtk, vtu, gmsh, obj, ply, su2, xdmf)

#: extension -> :class:`Format`
FORMATS: dict[str, Format] = {m.FORMAT.name: m.FORMAT for m in _MODULES}

#: Formats that write per-node arrays (``contour_point``, ``velocity``).
POINT_DATA_FORMATS = tuple(name for name, f in FORMATS.items() if f.point_data)

#: Gmsh file versions offered by ``--msh-version``, the default first.
MSH_VERSIONS = FORMATS["msh"].versions

__all__ = [
    "FORMATS",
    "MSH_VERSIONS",
    "POINT_DATA_FORMATS",
    "Format",
    "format_for",
    "mesh_files",
    "pvd_bytes",
    "read_mesh",
    "write_mesh",
]


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


def write_mesh(mesh: Mesh, path: str, fmt: str | None = None, msh_version: str = "2.2") -> str:
    """Write ``mesh`` to ``path`` (``-`` is stdout) in ``fmt`` or by extension; return
    the format's name."""
    fmt = format_for(path, fmt)
    form = FORMATS[fmt]
    version = None
    if form.versions:
        if msh_version not in form.versions:
            raise OptionError(f"--msh-version must be one of {', '.join(form.versions)}")
        version = msh_version
    if path == "-":
        if not form.stdout:
            raise OptionError(f"{fmt} writes two files; it cannot go to stdout")
        with tempfile.TemporaryDirectory() as d:
            tmp = os.path.join(d, f"mesh.{fmt}")
            _run(form, mesh, tmp, version, "-")
            write_bytes(Path(tmp).read_bytes(), "-")
        return fmt
    if form.sidecar is not None:
        _write_with_sidecar(form, mesh, path, version)
        return fmt
    with atomic_path(path) as tmp:
        _run(form, mesh, tmp, version, path)
    return fmt


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
        return [(p.name, p.read_bytes()) for p in [*others, main]]


def _write_with_sidecar(form: Format, mesh: Mesh, path: str, version) -> None:
    """Write both files in the system's temporary folder, copy them into a temporary
    folder next to ``path``, then move them into place.  Written elsewhere first
    because h5py, writing the sidecar onto a full disk, reports the error and then
    crashes the process (SIGSEGV at exit); a copy that does not fit is one line."""
    target = output_target(path)
    folder = check_folder(str(target))
    side = output_target(str(target.with_suffix(form.sidecar)))
    with tempfile.TemporaryDirectory() as first:
        made = Path(first) / target.name
        _run(form, mesh, str(made), version, path)
        try:
            with tempfile.TemporaryDirectory(prefix=f".{target.name}.", dir=folder) as d:
                tmp = Path(d) / target.name
                for src, dst in ((made.with_suffix(form.sidecar), tmp.with_suffix(form.sidecar)),
                                 (made, tmp)):  # fmt: skip
                    shutil.copyfile(src, dst)
                    os.chmod(dst, 0o644)
                os.replace(tmp.with_suffix(form.sidecar), side)
                os.replace(tmp, target)
        except OSError as exc:
            raise WriteError(f"{path}: cannot write: {exc.strerror or exc}") from None


def _run(form: Format, mesh: Mesh, tmp: str, version, path: str) -> None:
    """Run a writer into ``tmp`` with meshio's console chatter kept off stdout and stderr;
    its errors become one :class:`WriteError` line naming ``path``."""
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            form.write(mesh, tmp, version)
    except DeformeshError:
        raise
    except OSError as exc:
        raise WriteError(f"{path}: cannot write: {exc}") from None
    except Exception as exc:  # a writer's own error (meshio): one line, no traceback
        raise WriteError(f"{path}: cannot write {form.name}: {exc}") from None
