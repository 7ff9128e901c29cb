"""``deformesh deform STATE -o STATE2``: stage 2."""

from __future__ import annotations

import click

from .. import files, pipeline, state
from .. import size as _size
from ..errors import InputError, SizeError
from ..options import MeshOptions, from_record
from . import progress
from .errors import handle_errors
from .options import (
    check_binary_stdout,
    output_option,
    quiet_option,
    say,
    stages,
    take,
)


@click.command("deform")
@click.argument("state_in", metavar="STATE", type=click.Path(dir_okay=False, allow_dash=True))
@output_option("Deformed state file to write ('-' for stdout).")
@stages("deform")
@quiet_option
@progress.progress_option
@handle_errors
def command(state_in: str, output: str, quiet: bool, progress_flag, **kwargs) -> None:
    """Move the selected nodes onto the contour without folding (stage 2)."""
    check_binary_stdout(output)
    files.check_outputs([output], [state_in, kwargs.get("size_field")])
    name = "<stdin>" if state_in == "-" else state_in
    st = state.loads(files.read_bytes(state_in), name, want="selected")
    given = take(MeshOptions, kwargs).stage("deform")
    _size.check_options(given["size"], given["size_field"])
    own = given["size"] is None and given["size_field"] is None  # select's, if it had one
    if own:
        del given["size"], given["size_field"]
    o = from_record(MeshOptions, st.options).replace(**given)
    size = st.size_function(name) if own else _size.make(o.size, o.size_field, st.laid.contour)
    line = progress.LiveLine(progress.mode(quiet, progress_flag))
    try:
        d = pipeline.run_deform(
            st.grid_contour,
            st.selection,
            o.replace(size_field=None),
            callback=line.deforming(name),
            size_function=size,
        )
    except SizeError as exc:
        if not own:
            raise
        raise InputError(f"{name}: its recorded size function: {exc}") from None
    finally:
        line.close()
    options = {**st.options, **o.stage("deform"), "size_field": None}
    rows = None if size is None else size.rows
    out = state.State(
        "deformed", st.contour, st.selection, d.points, options, rows, st.laid, st.stacks
    )
    files.write_bytes(state.dumps(out), output)
    say(
        quiet,
        f"{st.contour.source}: deformed in {d.stats.solves} solves "
        f"({d.stats.halvings} step halvings)",
    )
