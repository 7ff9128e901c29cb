"""``deformesh select CONTOUR -o STATE``: stage 1."""

from __future__ import annotations

import click

from .. import files, pipeline, state
from ..options import MeshOptions
from ..readers import load_contour
from .errors import handle_errors
from .options import check_binary_stdout, output_option, quiet_option, say, stages, take


@click.command("select")
@click.argument("contour", type=click.Path(dir_okay=False, allow_dash=True))
@output_option("State file to write ('-' for stdout).")
@stages("select", "read")
@quiet_option
@handle_errors
def command(contour: str, output: str, quiet: bool, **kwargs) -> None:
    """Lay the background grid and pick one grid node per contour point (stage 1)."""
    check_binary_stdout(output)
    o = take(MeshOptions, kwargs)
    c = load_contour(contour, None, o.decimal, o.tolerance, o.element_id, o.resample)
    sel = pipeline.run_select(c, o)
    options = {**o.stage("read"), **o.stage("select")}
    files.write_bytes(state.dumps(state.State("selected", c, sel, options=options)), output)
    g = sel.grid
    say(
        quiet,
        f"{c.source}: selected {c.n} grid nodes on a {g.nx}x{g.ny} grid "
        f"(h = {sel.h:.4g}), {sel.extra_nodes} extra boundary nodes",
    )
