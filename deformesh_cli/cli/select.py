"""``deformesh select CONTOUR -o STATE``: stage 1."""

from __future__ import annotations

import click

from .. import files, pipeline, state
from .. import size as _size
from ..options import MeshOptions
from ..readers import load_contour
from .errors import handle_errors
from .options import check_binary_stdout, fields, output_option, quiet_option, say, stages, take


@click.command("select")
@click.argument("contour", type=click.Path(dir_okay=False, allow_dash=True))
@output_option("State file to write ('-' for stdout).")
@stages("select", "read", "layers")
@fields(MeshOptions, "size", "size_field")
@quiet_option
@handle_errors
def command(contour: str, output: str, quiet: bool, **kwargs) -> None:
    """Lay the background grid and pick one grid node per contour point (stage 1).

    A size function given here is recorded for ``deform`` (which uses it unless given
    one of its own) and, on the graded grid, refines the quadtree where it asks for
    smaller cells."""
    check_binary_stdout(output)
    o = take(MeshOptions, kwargs)
    _size.check_options(o.size, o.size_field)
    files.check_outputs([output], [contour, o.size_field])
    c = load_contour(contour, None, o.decimal, o.tolerance, o.element_id, o.resample, o.stroke)
    options = {**o.stage("read"), **o.stage("select"), **o.stage("layers")}
    laid, stacks = state.laid_for(c, options, pipeline.grid_mode(o.grid, o.h) == "graded")
    size = _size.make(o.size, o.size_field, laid.contour)
    sel = pipeline.run_select(laid.grid, o, size_function=size)
    if o.size is not None:
        options["size"] = o.size
    rows = None if size is None else size.rows  # (a field's rows, never its path)
    st = state.State("selected", c, sel, options=options, size_field=rows, laid=laid, stacks=stacks)
    files.write_bytes(state.dumps(st), output)
    g = sel.grid
    say(
        quiet,
        f"{c.source}: selected {c.n} grid nodes on a {g.nx}x{g.ny} grid "
        f"(h = {sel.h:.4g}), {sel.extra_nodes} extra boundary nodes",
    )
