"""``deformesh adapt MESH -o OUT --monitor EXPR``: move a mesh's nodes to follow a monitor."""

from __future__ import annotations

import contextlib
import io
import os
import re
import time

import click
import numpy as np

from .. import adapt as _adapt
from .. import files, formats
from ..errors import InputError, OptionError, WriteError, naming, printable
from ..formats._common import GROUP_DATA, PHYSICAL_DATA
from ..formats.read import checked, contour_nodes, read_meshio
from ..mesh import as_triangles, guarded
from . import progress
from .errors import handle_errors
from .options import OutputPath, json_option, quiet_option, say

#: meshio's name for each output extension it writes here (Gmsh 2.2 for ``.msh``: the
#: version every solver reads; legacy VTK 4.2, binary, which VTK's own reader reads).
_MESHIO_FORMATS = {".msh": "gmsh22", ".vtu": "vtu", ".vtk": "vtk42", ".xdmf": "xdmf"}


#: Options of meshio's writers: Gmsh as ASCII, as solvers read it.
_WRITE_OPTIONS = {"gmsh22": {"binary": False}}


@click.command("adapt")
@click.argument("mesh_path", metavar="MESH", type=click.Path(dir_okay=False))
@click.option(
    "-o", "--output", required=True, type=OutputPath(allow_dash=False),
    help="Adapted mesh to write (.msh, .vtu, .vtk or .xdmf): the same cells, groups and "
    "data, the nodes moved.",
)  # fmt: skip
@click.option(
    "--monitor",
    metavar="EXPR",
    help="Monitor M(x, y) > 0, in the --size grammar: cells shrink where M is large, "
    "toward every cell holding the same integral of M.",
)
@click.option(
    "--field",
    metavar="NAME",
    help="Build the monitor from MESH's point field NAME: 1 + alpha |grad u|^2 / "
    "max |grad u|^2 (--kind gradient) or 1 + alpha |H u| / max |H u| (--kind hessian), "
    "recovered at the nodes.",
)
@click.option(
    "--alpha",
    type=float,
    help="With --field: how much larger M gets where the field varies most "
    f"[default: {_adapt.DEFAULT_ALPHA:g}].",
)
@click.option(
    "--kind",
    type=click.Choice(_adapt.KINDS),
    help="With --field: what of the field the monitor follows [default: gradient].",
)
@click.option(
    "--reference",
    "reference_path",
    metavar="MESH2",
    type=click.Path(dir_okay=False),
    help="Adapt from MESH2's nodes and relative to its cells (the same triangles as MESH), "
    "so that repeated solve-adapt cycles do not compound; default: MESH itself.",
)
@click.option(
    "--boundary",
    type=click.Choice(("slide", "fixed")),
    default="slide",
    show_default=True,
    help="slide: boundary nodes on straight runs (a far field's box sides) slide along "
    "them, corners and contour points stay; fixed: every boundary node stays.",
)
@click.option(
    "--steps",
    type=click.IntRange(min=1, max=_adapt.MAX_ADAPT_STEPS),
    default=_adapt.ADAPT_STEPS,
    show_default=True,
    help="Solves of the velocity at least: the pseudo-time between two solves is at most "
    "1/N (and short enough that no cell's shape changes by more than 0.8 in it).",
)
@click.option(
    "--png",
    type=OutputPath(allow_dash=False),
    help="Also draw the adapted mesh, each triangle coloured by the monitor (the mean of "
    "its nodes'), to this PNG (needs matplotlib).",
)
@click.option("-f", "--force", is_flag=True, help="Replace an output deformesh did not write.")
@json_option("Print the report as JSON on stdout.")
@quiet_option
@progress.progress_option
@handle_errors
def command(
    mesh_path, output, monitor, field, alpha, kind, reference_path, boundary, steps, png,
    force, as_json, quiet, progress_flag,
) -> None:  # fmt: skip
    """Move a mesh's nodes so its cells follow a monitor: the same triangles (and quads),
    never tangled (r-adaptation by the div-curl deformation).  A deformesh mesh's contour
    points stay where they are, bit for bit.

    The monitor is an expression (--monitor) or follows a point field of MESH
    (--field), as a solver wrote it.

    MESH is any mesh of triangles (and quads) meshio reads; its point data are carried to the new
    node positions by linear interpolation in the old mesh (integer arrays, which
    label nodes, stay as they are) into .vtu, .vtk and .xdmf, and into .msh (Gmsh
    2.2) as $NodeData beside the physical groups.
    """
    t0 = time.perf_counter()
    suffix = "." + output.rsplit(".", 1)[-1].lower() if "." in output else ""
    if suffix not in _MESHIO_FORMATS:
        raise click.UsageError(
            f"{output}: adapt writes {', '.join(_MESHIO_FORMATS)}; give one of those extensions"
        )
    if (monitor is None) == (field is None):
        raise click.UsageError("give one of --monitor EXPR and --field NAME")
    if field is None and (alpha is not None or kind is not None):
        raise click.UsageError("--alpha and --kind shape a --field monitor; give --field NAME")
    alpha = _adapt.DEFAULT_ALPHA if alpha is None else alpha
    kind = kind or "gradient"
    code = _monitor(monitor) if monitor is not None else None
    outputs = [output] + ([png] if png else [])
    files.check_outputs(outputs, [mesh_path] + ([reference_path] if reference_path else []))
    m = _read(mesh_path)
    _check_names(m, mesh_path, suffix)
    if suffix == ".msh":  # (refused before the work, not after it)
        for k, v in m.point_data.items():
            _node_data(k, v, output)
    points, tri, quads = checked(m, mesh_path, quads=True)
    guard = None
    if len(quads):  # (solved on the quads' halves; all four corners of each kept unfolded)
        guard = guarded(tri, quads)
        tri = as_triangles(tri, quads)
    start = points
    if reference_path is not None:
        start, ref_tri, ref_quads = checked(_read(reference_path), reference_path, quads=True)
        ref_tri = as_triangles(ref_tri, ref_quads)
        if ref_tri.shape != tri.shape or len(start) != len(points):
            raise InputError(
                f"{reference_path}: has {len(start)} nodes and {len(ref_tri)} triangles, "
                f"{mesh_path} {len(points)} and {len(tri)}; --reference needs the same triangles"
            )
        if (ref_tri != tri).any():
            k = int(np.argmax((ref_tri != tri).any(axis=1)))
            raise InputError(
                f"{reference_path}: triangle {k} is {ref_tri[k].tolist()}, in {mesh_path} "
                f"{tri[k].tolist()}; --reference needs the same triangles"
            )
    if field is not None:
        if field not in m.point_data:
            have = ", ".join(sorted(m.point_data)) or "none"
            raise InputError(f"{mesh_path}: no point field {field!r} (point fields: {have})")
        _adapt.check_mesh(points, tri, mesh_path)
        nodal = _adapt.field_monitor(
            points, tri, m.point_data[field], alpha, kind, f"{mesh_path}: field {field!r}"
        )
        code = _adapt.interpolated(points, tri, nodal)
    held = _contour_nodes(m, len(points), mesh_path)
    line = progress.LiveLine(progress.mode(quiet, progress_flag))

    def on_solve(t: float, solves: int) -> None:
        line.say(f"deformesh: {mesh_path}: adapting, pseudo-time {t:.2f}, {solves} solves")

    with naming(reference_path or mesh_path), contextlib.closing(line):
        res = _adapt.adapt(
            start, tri, code, steps, source=reference_path or mesh_path, held=held,
            slide=boundary == "slide", guard=guard, progress=on_solve,
        )  # fmt: skip
        new = res.points
        carried = {
            k: v
            if np.issubdtype(np.asarray(v).dtype, np.integer)
            else _adapt.carry(points, tri, new, v)
            for k, v in m.point_data.items()
        }
    picture = None
    if png:  # (drawn before any file is written: no mesh without its picture)
        from .. import plot

        m_new = _adapt.monitor_values(code, new, mesh_path)
        picture = plot.render(
            new, tri, title=f"{output}: adapted, sigma/mu {res.report['sigma_over_mu']:.3f}",
            values=("monitor M (triangle's nodes' mean)", m_new[tri].mean(axis=1)),
        )  # fmt: skip
    xyz = np.array(m.points, dtype=np.float64, copy=True)
    xyz[:, :2] = new
    data = carried
    import meshio

    fmt = _MESHIO_FORMATS[suffix]
    tags, names = _groups(m, mesh_path)
    cell_data = {k: v for k, v in m.cell_data.items() if k not in _GROUP_ARRAYS}
    if tags is not None:  # the same groups in every output, under each format's names
        if fmt == "gmsh22":
            cell_data.update({"gmsh:physical": tags, "gmsh:geometrical": tags})
        else:
            cell_data.update({GROUP_DATA: tags, PHYSICAL_DATA: tags})
    if fmt == "gmsh22":  # the groups, and the point data as $NodeData
        cell_data = {k: v for k, v in cell_data.items() if k.startswith("gmsh:")}
        data = {k: _node_data(k, v, output) for k, v in data.items() if not k.startswith("gmsh:")}
    out = meshio.Mesh(xyz, m.cells, point_data=data, cell_data=cell_data, field_data=names)
    if fmt == "xdmf":  # (its sidecar named after the output, never after a staged file)
        main, side = formats.xdmf.render_meshio(out, os.path.basename(output))
        formats.write_pair(output, formats.xdmf.FORMAT.sidecar, main, side)
    else:
        _write_meshio(out, output, fmt, names)
    if picture is not None:
        files.write_bytes(picture, png)
    report = {"input": mesh_path, "output": output}
    if monitor is not None:
        report["monitor"] = monitor
    else:
        report.update(field=field, kind=kind, alpha=alpha)
    if reference_path is not None:
        report["reference"] = reference_path
    report.update(res.report)
    if len(quads):  # (the mesh's own cells, not the halves the quads were solved on)
        report.update(triangles=len(tri) - 2 * len(quads), quads=len(quads))
    report["seconds"] = round(time.perf_counter() - t0, 3)
    if as_json:
        files.write_stdout(files.to_json(report))
    r = report
    say(
        quiet,
        f"{mesh_path} -> {output}: {r['moved_nodes']} of {r['nodes']} nodes moved "
        f"({r['boundary_nodes_held']} held, {r['boundary_nodes_sliding']} sliding), "
        f"{r['triangles']} triangles"
        + (f" and {r['quads']} quads" if r.get("quads") else "")
        + f" kept, smallest angle {r['smallest_angle']:.1f}; "
        f"sigma/mu {r['sigma_over_mu_before']:.3f} -> {r['sigma_over_mu']:.3f}, volume ratio "
        f"{r['volume_ratio_before']:.2f} -> {r['volume_ratio']:.2f} ({r['seconds']:.2f} s)",
    )


#: Per output, what a point-data or group name may not hold to be copied into the file
#: as it is: a control character (a newline ends a .msh or .vtk line) or a double quote
#: (it ends a .msh name and an XML attribute) anywhere; white space in a legacy VTK name;
#: markup in an XML attribute (.vtu, .xdmf).
_NOT_IN_NAME = {
    ".msh": r'["\x00-\x1f\x7f-\x9f]',
    ".vtk": r'["\s\x00-\x1f\x7f-\x9f]',
    ".vtu": r'["<>&\x00-\x1f\x7f-\x9f]',
    ".xdmf": r'["<>&\x00-\x1f\x7f-\x9f]',
}


def _check_names(m, path: str, suffix: str) -> None:
    """Refuse, before any work, a point-data or group name that the output cannot hold as
    it is (:data:`_NOT_IN_NAME`), naming it: a file written with it would not read back."""
    bad = re.compile(_NOT_IN_NAME[suffix])
    for what, names in (("point data", m.point_data), ("group", m.field_data)):
        for name in names:
            found = bad.search(name)
            if found is not None:
                raise InputError(
                    f"{path}: {what} name {printable(name)} cannot be written into a {suffix} "
                    f"file as it is (it holds {printable(found[0])}); rename it or write "
                    "another format"
                )


#: The cell data arrays that carry physical groups, in the formats adapt reads.
_GROUP_ARRAYS = (GROUP_DATA, PHYSICAL_DATA, "gmsh:geometrical", "su2:tag")


def _groups(m, path: str) -> tuple[list[np.ndarray] | None, dict[str, np.ndarray]]:
    """The input's physical groups: per cell block, each cell's tag, and the names (name
    -> ``[tag, dimension]``, meshio's Gmsh convention); ``(None, {})`` for a mesh without
    groups.  From ``gmsh:physical`` (.msh, and deformesh's .vtu and .xdmf), ``group``
    (deformesh's .vtk, and its older files), or an SU2 file's markers (named in its
    ``MARKER_TAG`` lines, in order, as meshio numbers them 1, 2, ...; its triangles,
    tagged 0, become the group ``domain``).  Field data that is not a group's
    ``(tag, dimension)`` (two whole numbers) is left out."""
    names = {}
    for k, v in m.field_data.items():  # (other field data, not groups: left out)
        v = np.asarray(v).ravel()
        pair = v[:2] if len(v) >= 2 and v.dtype.kind in "iuf" else np.array([np.nan])
        if (np.abs(pair) < 2**31).all() and (pair == np.round(pair)).all():
            names[k] = pair.astype(np.int64)
    for key in (PHYSICAL_DATA, GROUP_DATA):
        if key in m.cell_data:
            return [np.asarray(t, dtype=np.int32).ravel() for t in m.cell_data[key]], names
    if "su2:tag" in m.cell_data and path.lower().endswith(".su2"):
        with open(path, errors="replace") as f:
            found = re.findall(r"^\s*MARKER_TAG\s*=\s*(\S+)", f.read(), re.M)
        names = {name: np.array([k + 1, 1]) for k, name in enumerate(found)}
        domain = len(found) + 1
        names.setdefault("domain", np.array([domain, 2]))
        tags = []
        for block, t in zip(m.cells, m.cell_data["su2:tag"]):
            t = np.asarray(t, dtype=np.int32).ravel()
            tags.append(np.where(t == 0, domain, t) if block.type == "triangle" else t)
        return tags, names
    return None, names


def _write_meshio(out, output: str, fmt: str, field_data) -> None:
    """meshio's writer for ``fmt`` into ``output``, atomically (a failure leaves no file)."""
    import meshio

    with files.atomic_path(output) as staged:
        try:  # (meshio's console chatter kept off stdout, where --json goes)
            with (
                contextlib.redirect_stdout(io.StringIO()),
                contextlib.redirect_stderr(io.StringIO()),
            ):
                meshio.write(staged, out, file_format=fmt, **_WRITE_OPTIONS.get(fmt, {}))
        except OSError as exc:
            raise WriteError(f"{output}: cannot write: {exc.strerror or exc}") from None
        if fmt in ("vtu", "vtk42"):  # (meshio writes no field data there: the group names)
            add = formats.vtu.add_field_data if fmt == "vtu" else formats.vtk.add_field_data
            add(staged, field_data)


def _monitor(text: str):
    """The monitor expression as a function of points (an OptionError if it is not one)."""
    from ..size import compile_expression

    code = compile_expression(text, "--monitor")
    if code.uses_distance:
        raise OptionError("--monitor: d (the distance to a contour) is not defined for a mesh")

    def monitor(q):
        try:
            return code(x=q[:, 0], y=q[:, 1])
        except (ArithmeticError, ValueError, TypeError) as exc:
            raise OptionError(f"--monitor {text!r} fails: {type(exc).__name__}: {exc}") from None

    return monitor


def _read(path: str):
    """A mesh of triangles and quads read by meshio (other 2D cells refused in one line)."""
    m = read_meshio(path)
    others = sorted({c.type for c in m.cells} - {"triangle", "quad", "line", "vertex"})
    if others:
        raise InputError(
            f"{path}: cells other than triangles and quads ({', '.join(others)}); adapt "
            "moves meshes of triangles and quads"
        )
    return m


def _node_data(name: str, values, output: str) -> np.ndarray:
    """A point array as meshio's Gmsh writer can put it in ``$NodeData``: 1, 3 or 9
    components (2 padded with a zero third, as Gmsh's vectors are 3D), as Python
    numbers (meshio writes each with ``repr``, which gives ``np.float64(0.5)`` for a
    numpy 2 scalar, which no reader takes)."""
    v = np.asarray(values)
    v = v.reshape(len(v), -1)
    if v.shape[1] == 2:
        v = np.column_stack([v, np.zeros(len(v), dtype=v.dtype)])
    if v.shape[1] not in (1, 3, 9):
        raise OptionError(
            f"{output}: point data {name!r} has {v.shape[1]} components, and Gmsh's $NodeData "
            "takes 1, 3 or 9; write .vtu, .vtk or .xdmf"
        )
    return np.array(v.tolist(), dtype=object)


def _contour_nodes(m, n: int, path: str) -> np.ndarray | None:
    """A deformesh mesh's contour and hole nodes (a mask), which stay where they are: the
    nodes its ``contour_point`` data number (.vtu, .vtk, .xdmf), or the nodes of the lines
    of every physical group (SU2 marker) but the box sides where they name a ``contour``
    (.msh, .su2).
    None for any other mesh."""
    from ..triangulate import BOX_SIDES

    marked = contour_nodes(m.point_data, n, path)
    if marked is not None:
        return marked
    tags, names = _groups(m, path)
    names = {int(v[0]): k for k, v in names.items() if v[-1] == 1}
    if tags is None or "contour" not in names.values():
        return None
    held = np.zeros(n, dtype=bool)
    for block, tag in zip(m.cells, tags):
        if block.type == "line":
            user = np.array([names.get(int(t)) not in BOX_SIDES for t in np.ravel(tag)])
            held[np.asarray(block.data)[user].ravel()] = True
    return held
