"""Mesh output formats, one module each, behind the registry :data:`FORMATS`.

Adding a format is a module with a ``write(mesh, path, version)`` function
(or, for a format with a sidecar, a ``render`` making both files' bytes) and a
:class:`~.format.Format` named ``FORMAT``, and its line in
:data:`_MODULES`.  :func:`write_mesh` is the one way a mesh reaches a file:
atomically (a failure leaves no file), with a format's sidecar moved into
place with it, meshio's console chatter kept quiet, and any writer error
turned into one :class:`~deformesh_cli.errors.WriteError` line.
"""

from __future__ import annotations

import contextlib
import io
import os
import tempfile
from pathlib import Path

from ..errors import DeformeshError, OptionError, WriteError
from ..files import atomic_path, check_folder, output_target, write_bytes
from ..files import check_outputs as check_files
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
    "check_outputs",
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
        _write_with_sidecar(form, mesh, path)
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
    form = FORMATS[fmt]
    if form.render is not None:
        main, second = _render(form, mesh, name, name)
        return [(str(Path(name).with_suffix(form.sidecar)), second), (name, main)]
    with tempfile.TemporaryDirectory() as d:
        write_mesh(mesh, os.path.join(d, name), fmt, msh_version)
        main = Path(d) / name
        others = sorted(p for p in Path(d).iterdir() if p != main)
        return [(p.name, p.read_bytes()) for p in [*others, main]]


def check_outputs(
    meshes: list[str],
    fmt: str,
    inputs: list,
    *,
    typed: bool,
    others: list[str] = (),
    force: bool = False,
) -> None:
    """Before any work, what writing the mesh files ``meshes`` in ``fmt`` (and the
    ``others``: a ``--png``, a ``.pvd``) would lose, refused (:func:`.files.check_outputs`):
    a file that is one of the run's ``inputs`` or another of its outputs; a symbolic
    link in place of a file the run names itself (the sidecars, and ``meshes`` and
    ``others`` unless ``typed``: the user named them, as ``-o``, not a batch); and,
    unless ``force``, an existing sidecar that does not start with the format's
    ``sidecar_mark`` (a user's file with the output's name)."""
    form = FORMATS[format_for(meshes[0], fmt)] if meshes else None
    side = [] if form is None or form.sidecar is None else [
        str(output_target(m).with_suffix(form.sidecar)) for m in meshes if m != "-"
    ]  # fmt: skip
    written = [*meshes, *others]
    check_files(written if typed else [], inputs, side if typed else written + side)
    if force:
        return
    mark = form.sidecar_mark if form is not None else b""
    for path in side:
        if not os.path.lexists(path):
            continue
        try:
            with open(path, "rb") as f:
                head = f.read(len(mark))
        except OSError as exc:
            raise WriteError(f"{path}: cannot read: {exc.strerror}") from None
        if not mark or head != mark:  # (a format without a mark: never known as ours)
            raise OptionError(
                f"{path}: exists and was not written by deformesh; writing its mesh would "
                "replace it (--force replaces it)"
            )


def _write_with_sidecar(form: Format, mesh: Mesh, path: str) -> None:
    """Make both files in memory, write them into a temporary folder next to ``path``,
    then move them into place: the sidecar first, created new (a symbolic link in its
    place is replaced by the file, never written through)."""
    main, second = _render(form, mesh, output_target(path).name, path)
    write_pair(path, form.sidecar, main, second)


def write_pair(path: str, sidecar: str, main: bytes, second: bytes) -> None:
    """Write ``main`` to ``path`` and ``second`` to its sidecar (``path`` with the suffix
    ``sidecar``) through a temporary folder next to them, then move them into place,
    the sidecar first: a failure leaves neither, and nothing else is left behind."""
    target = output_target(path)
    folder = check_folder(str(target))
    side = target.with_suffix(sidecar)
    try:
        with tempfile.TemporaryDirectory(prefix=f".{target.name}.", dir=folder) as d:
            tmp = Path(d) / target.name
            for data, dst in ((second, tmp.with_suffix(sidecar)), (main, tmp)):
                dst.write_bytes(data)
                os.chmod(dst, 0o644)
            os.replace(tmp.with_suffix(sidecar), side)
            os.replace(tmp, target)
    except OSError as exc:
        raise WriteError(f"{path}: cannot write: {exc.strerror or exc}") from None


def _render(form: Format, mesh: Mesh, name: str, path: str) -> tuple[bytes, bytes]:
    """``form.render`` with its errors as :func:`_run` reports them."""
    try:
        return form.render(mesh, name)
    except DeformeshError:
        raise
    except Exception as exc:  # a writer's own error (meshio, h5py): one line
        raise WriteError(f"{path}: cannot write {form.name}: {exc}") from None


def _run(form: Format, mesh: Mesh, tmp: str, version, path: str) -> None:
    """Run a writer into ``tmp`` with meshio's console chatter kept off stdout and stderr;
    its errors become one :class:`WriteError` line naming ``path``."""
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            form.write(mesh, tmp, version)
    except DeformeshError:
        raise
    except OSError as exc:  # (its text without the staged file's name)
        why = (exc.strerror or str(exc)).replace(tmp, path)
        raise WriteError(f"{path}: cannot write: {why}") from None
    except Exception as exc:  # a writer's own error (meshio): one line, no traceback
        why = str(exc).replace(tmp, path)  # (the user's file, never the staged one)
        raise WriteError(f"{path}: cannot write {form.name}: {why}") from None
