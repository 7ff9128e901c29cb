"""``deformesh triangulate STATE2 -o MESH``: stage 3."""

from __future__ import annotations

import time

import click

from .. import files, pipeline, state
from ..errors import FoldError, InputError, OptionError, SizeError
from ..options import MeshOptions, from_record
from .errors import handle_errors
from .options import (
    force_option,
    json_option,
    output_option,
    png_option,
    quiet_option,
    stages,
    take,
)
from .report import check_mesh_output, check_outputs, finish


@click.command("triangulate")
@click.argument("state_in", metavar="STATE", type=click.Path(dir_okay=False, allow_dash=True))
@output_option("Mesh file to write; the format follows the extension.")
@stages("triangulate", "write")
@png_option
@force_option
@json_option()
@quiet_option
@handle_errors
def command(
    state_in: str, output: str, png, force: bool, as_json: bool, quiet: bool, **kwargs
) -> None:
    """Keep the triangles inside the contour and write the mesh (stage 3)."""
    t0 = time.perf_counter()
    given = take(MeshOptions, kwargs)
    fmt = check_mesh_output(output, given.fmt, as_json)
    check_outputs(output, fmt, png, [state_in], force)
    name = "<stdin>" if state_in == "-" else state_in
    st = state.loads(files.read_bytes(state_in), name, want="deformed")
    # the size function the deformation used, from the state file: its report
    o = from_record(MeshOptions, st.options).replace(
        **given.stage("triangulate"), **given.stage("write")
    )
    deformed = pipeline.Deformed(st.selection, st.points)
    try:
        size = st.size_function(name)
        if st.stacks is not None and o.merge_extra == "keep":
            raise OptionError(
                "--merge-extra keep would leave grid nodes between the layers' top nodes "
                f"of {name}; the layers need them taken out"
            )
        if st.stacks is not None:
            pipeline.check_layer_cells(o)
        core = pipeline.core_options(o) if st.stacks is not None else o
        mesh, report = pipeline.run_triangulate(st.laid, deformed, core, size_function=size)
        report.update(pipeline.selection_report(st.selection))
        if st.stacks is not None:  # (the layers and the mesh of their top, joined)
            mesh, report = pipeline.join_layers(
                st.contour, st.stacks, mesh, report, st.selection, o
            )
        box = st.selection.grid.box if o.exterior else None
        mesh, report = pipeline.finish_mesh(st.contour, mesh, report, o, box, st.stacks)
    except FoldError as exc:  # (the state's deformed points are what folds)
        raise FoldError(f"{name}: {exc}") from None
    except SizeError as exc:
        raise InputError(f"{name}: its recorded size function: {exc}") from None
    finish(
        st.contour,
        mesh,
        report,
        output,
        fmt,
        as_json=as_json,
        quiet=quiet,
        t0=t0,
        msh_version=o.msh_version,
        png=png,
    )
