"""``deformesh plot MESH -o PNG``: a picture of a mesh."""

from __future__ import annotations

import click

from .. import files, formats
from ..formats.read import contour_nodes
from ..options import MeshOptions
from ..readers import load_contour
from .errors import handle_errors
from .options import (
    BoxType,
    check_binary_stdout,
    contour_reading,
    output_option,
    quiet_option,
    take,
)


@click.command("plot")
@click.argument("mesh_path", metavar="MESH", type=click.Path(dir_okay=False))
@output_option("PNG file to write ('-' for stdout).")
@click.option(
    "--contour",
    "contour_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Draw this contour's points over the mesh.",
)
@click.option(
    "--window",
    type=BoxType(),
    default=None,
    help="Draw only this part of the plane, X0,Y0,X1,Y1 (the whole mesh in an inset).",
)
@click.option(
    "--zoom",
    type=click.Choice(["contour", "mesh"]),
    default="contour",
    show_default=True,
    help="Without --window: frame the contour's points (those of --contour, or the "
    "mesh's point data contour_point), so a far field shows its body, or the whole mesh.",
)
@click.option(
    "--colour",
    type=click.Choice(["radius-ratio", "angle"]),
    default="radius-ratio",
    show_default=True,
    help="Shade each triangle by its radius ratio 2r/R or its smallest angle.",
)
@contour_reading()
@quiet_option
@handle_errors
def command(
    mesh_path: str,
    output: str,
    contour_path: str | None,
    window,
    zoom: str,
    colour: str,
    quiet: bool,
    **kwargs,
) -> None:
    """Draw a mesh to PNG: triangles shaded by radius ratio (or angle) with their edges,
    the boundary, a histogram."""
    from .. import plot  # matplotlib loads only here

    o = take(MeshOptions, kwargs)
    check_binary_stdout(output)
    if window is not None and not (window[0] < window[2] and window[1] < window[3]):
        raise click.BadParameter("X0 < X1 and Y0 < Y1 are needed", param_hint="--window")
    files.check_outputs([output], [mesh_path, contour_path])
    points, tri, quads, data = formats.read_mesh(mesh_path, point_data=True, quads=True)
    cpts = None
    if contour_path is not None:
        c = load_contour(
            contour_path, None, o.decimal, o.tolerance, o.element_id, o.resample, o.stroke
        )
        cpts = c.points
    if window is not None:
        window = plot.clipped_window(points, window, mesh_path)
    if window is None and zoom == "contour":
        marked = contour_nodes(data, len(points), mesh_path)
        window = plot.contour_window(points, marked, cpts)
    plot.draw(
        points,
        tri,
        output,
        contour_points=cpts,
        title=f"{mesh_path}: {len(points)} nodes, {len(tri)} triangles"
        + (f", {len(quads)} quads" if len(quads) else ""),
        window=window,
        colour=colour,
        quads=quads,
    )
