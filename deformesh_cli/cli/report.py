"""Writing a finished mesh and reporting it: what ``triangulate`` and ``all`` share."""

from __future__ import annotations

import time

import click

from .. import files, formats
from ..contour import Contour
from ..mesh import Mesh
from .options import check_binary_stdout, say


def check_mesh_output(output: str, fmt: str | None, as_json: bool) -> str:
    """The output's format; ``--json`` and a mesh on stdout cannot share stdout, and a
    binary format is not written to a terminal."""
    if as_json and output == "-":
        raise click.UsageError("--json and -o - both use stdout; write the mesh to a file")
    fmt = formats.format_for(output, fmt)  # an OptionError is a usage error
    if formats.FORMATS[fmt].binary:
        check_binary_stdout(output)
    return fmt


def check_outputs(
    output: str, fmt: str, png: str | None, inputs: list, force: bool = False
) -> None:
    """Before any work: the mesh, its sidecar and the picture are not an input of the run
    nor one another, the sidecar is not a link, nor a file deformesh did not write
    (unless ``force``)."""
    others = [] if png is None else [png]
    formats.check_outputs([output], fmt, inputs, typed=True, others=others, force=force)


def finish(
    contour: Contour,
    mesh: Mesh,
    report: dict,
    output: str,
    fmt: str,
    *,
    as_json: bool,
    quiet: bool,
    t0: float,
    msh_version: str,
    png: str | None,
) -> None:
    """Write the mesh (and its picture), then the summary: JSON on stdout, a line on stderr."""
    picture = None
    if png is not None:  # drawn first: a failure here leaves no mesh file either
        from .. import plot

        files.check_folder(png)
        picture = plot.render(
            mesh.points,
            mesh.triangles,
            boundary=mesh.lines,
            contour_points=mesh.points[: mesh.n_contour],
            title=f"{output}: {mesh.n_nodes} nodes, {len(mesh.triangles)} triangles"
            + (f", {len(mesh.quads)} quads" if len(mesh.quads) else ""),
            window=plot.zoom_window(mesh.points[: mesh.n_contour]),  # (as plot's --zoom)
            quads=mesh.quads,
        )
    if picture is None:
        formats.write_mesh(mesh, output, fmt, msh_version)
    else:  # the picture staged first and moved into place only once the mesh is written:
        # both files or neither (a full disk fails the one that does not fit)
        with files.atomic_path(png) as staged:
            files.write_bytes(picture, staged, name=png)
            formats.write_mesh(mesh, output, fmt, msh_version)
    report = {
        "input": contour.source,
        "output": output,
        "format": fmt,
        **report,
        "seconds": round(time.perf_counter() - t0, 3),
    }
    report["notes"] = list(contour.notes) + list(report.get("notes", []))
    if as_json:
        files.write_stdout(files.to_json(report))
    for note in report["notes"]:
        say(quiet, f"note: {contour.source}: {note}")
    say(quiet, summary_line(report))


def summary_line(r: dict) -> str:
    """The one line on stderr that sums up a mesh (the triangles' angles and areas; the
    quads and layers counted where there are some)."""
    quads = f"{r['quads']} quads, " if r.get("quads") else ""
    layers = r.get("layers")
    if layers:
        quads += (
            f"{layers['layers']} layers on {layers['stacks']} stacks "
            f"({layers['shortened_stacks']} shortened), "
        )
    return (
        f"{r['input']} -> {r['output']}: {r['nodes']} nodes, {r['triangles']} triangles, "
        f"{quads}angles {r['min_angle']:.1f}-{r['max_angle']:.1f} deg, smallest area "
        f"{r['smallest_area']:.3g}, {r['extra_boundary_nodes']} extra boundary nodes"
        f", contract {r['contract']} ({r['seconds']:.2f} s)"
    )
