"""``deformesh plot MESH -o PNG``: a picture of a mesh."""

from __future__ import annotations

import click

from .. import files, formats
from ..options import MeshOptions
from ..readers import load_contour
from .errors import handle_errors
from .options import check_binary_stdout, contour_reading, output_option, quiet_option, take


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
@contour_reading()
@quiet_option
@handle_errors
def command(mesh_path: str, output: str, contour_path: str | None, quiet: bool, **kwargs) -> None:
    """Draw a mesh to PNG: triangles shaded by radius ratio, the boundary, a histogram."""
    from .. import plot  # matplotlib loads only here

    o = take(MeshOptions, kwargs)
    check_binary_stdout(output)
    files.check_outputs([output], [mesh_path, contour_path])
    points, tri = formats.read_mesh(mesh_path)
    cpts = None
    if contour_path is not None:
        c = load_contour(
            contour_path, None, o.decimal, o.tolerance, o.element_id, o.resample, o.stroke
        )
        cpts = c.points
    plot.draw(
        points,
        tri,
        output,
        contour_points=cpts,
        title=f"{mesh_path}: {len(points)} nodes, {len(tri)} triangles",
    )
