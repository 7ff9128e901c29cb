"""Command-line interface: parse, call the core, write, report.

stdout carries data only (a state file, a mesh, ``--json``); messages go to
stderr.  Exit codes: 0 ok, 1 processing failure, 2 usage error.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import sys
import time

import click

from . import __version__, batch, files, formats, pipeline, quality, state
from . import size as _size
from .deform import DEFAULT_STEPS, SOLVERS
from .errors import DeformeshError, OptionError
from .readers import load_contour
from .select import DEFAULT_MAX_NODES


class BoxType(click.ParamType):
    name = "XMIN,YMIN,XMAX,YMAX"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            v = tuple(float(s) for s in value.split(","))
        except ValueError:
            self.fail(f"{value!r} is not four numbers XMIN,YMIN,XMAX,YMAX", param, ctx)
        if len(v) != 4:
            self.fail(f"{value!r} has {len(v)} numbers, expected XMIN,YMIN,XMAX,YMAX", param, ctx)
        return v


def _positive(ctx, param, value):
    if value is not None and not value > 0:
        raise click.BadParameter("must be > 0")
    return value


def _handle_errors(fn):
    """Turn core errors into one-line messages and exit codes; never a traceback."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except OptionError as exc:
            raise click.UsageError(str(exc)) from None
        except DeformeshError as exc:
            click.echo(f"deformesh: error: {exc}", err=True)
            sys.exit(1)
        except MemoryError:
            click.echo(
                "deformesh: error: out of memory; lower --max-nodes or give a larger --h", err=True
            )
            sys.exit(1)

    return wrapper


def _say(quiet: bool, msg: str) -> None:
    if not quiet:
        click.echo(f"deformesh: {msg}", err=True)


def _check_binary_stdout(out: str) -> None:
    if out == "-" and sys.stdout.isatty():
        raise click.UsageError("refusing to write binary data to a terminal; use -o FILE or a pipe")


def _read_contour(path: str, decimal: str = ".", tolerance=None, element_id=None, resample=None):
    return load_contour(path, None, decimal, tolerance, element_id, resample)


contour_options = [
    click.option(
        "--decimal",
        type=click.Choice([".", ","]),
        default=".",
        show_default=True,
        help="Decimal mark of the CSV numbers; with ',' the delimiter is ';', tab or spaces.",
    ),
    click.option(
        "--tolerance",
        default=None,
        metavar="TOL",
        help="SVG: largest gap between a curve and its chords, in drawing units, or "
        "a percentage of the drawing's diagonal ('0.5%').  Default: 0.1%.",
    ),
    click.option(
        "--id",
        "element_id",
        default=None,
        metavar="ID",
        help="SVG: mesh only the element with this id (a shape or a group). "
        "Default: every filled shape.",
    ),
    click.option(
        "--resample",
        default=None,
        metavar="SPACING",
        help="Re-space the contour evenly (corners kept) at SPACING, in contour units "
        "or as a percentage of its diagonal ('1%'). The given points are then "
        "no longer all boundary nodes.",
    ),
]

select_options = [
    click.option(
        "--h",
        "h",
        type=float,
        callback=_positive,
        default=None,
        help="Grid step. Default: Appendix A's 0.9*d_c/sqrt(2), d_c the smallest "
        "distance between two contour points.",
    ),
    click.option(
        "--box",
        type=BoxType(),
        default=None,
        help="Background box XMIN,YMIN,XMAX,YMAX (must contain the contour). "
        "Default: the contour's bounding box grown by --margin.",
    ),
    click.option(
        "--margin",
        type=float,
        default=None,
        help="Gap between the contour's bounding box and the background box, in "
        "contour units. Default: 3 grid steps.",
    ),
    click.option(
        "--strict",
        is_flag=True,
        help="Fail instead of adding boundary nodes where consecutive contour points "
        "select grid nodes that are not neighbours.",
    ),
    click.option(
        "--max-nodes",
        type=click.IntRange(min=4),
        default=DEFAULT_MAX_NODES,
        show_default=True,
        help="Refuse grids with more nodes than this (memory guard).",
    ),
    *contour_options,
    click.option(
        "--exterior",
        is_flag=True,
        help="Mesh the box minus the contour (e.g. an airfoil in a far-field box). "
        "Default margin: the contour's larger extent.",
    ),
    click.option(
        "--grid",
        "grid",
        type=click.Choice(pipeline.GRIDS),
        default="auto",
        show_default=True,
        help="'adapt': select on the points evenly re-spaced between corners with h "
        "their median spacing, then slide each node along the contour to its "
        "point; 'uniform': Appendix A's grid; 'auto': adapt when the median "
        "spacing is over 4x the smallest (and no --h, not --exterior).",
    ),
]
size_options = [
    click.option(
        "--size",
        "size_expr",
        default=None,
        metavar="EXPR",
        help="Size function f: cells end with areas proportional to f. A numpy "
        "expression in x, y and d (distance to the contour), e.g. '0.2 + d'.",
    ),
    click.option(
        "--size-field",
        default=None,
        type=click.Path(dir_okay=False),
        help="Size function as values on a regular grid: rows x, y, f (CSV or .npy).",
    ),
]
steps_option = click.option(
    "--steps",
    type=click.IntRange(min=1),
    default=DEFAULT_STEPS,
    show_default=True,
    help="Pseudo-time steps of the deformation.",
)
solver_option = click.option(
    "--solver",
    type=click.Choice(SOLVERS),
    default="auto",
    show_default=True,
    help="Linear solver per step: sparse LDL^T ('direct'), multigrid-preconditioned CG ('amg'), "
    "or 'auto' (direct on the band, and up to 60,000 free nodes on a whole grid).",
)
solve_option = click.option(
    "--solve",
    type=click.Choice(pipeline.SOLVES),
    default="band",
    show_default=True,
    help="Deform only a narrow band of cells around the path ('band': at least 4 cells, "
    "3 times the farthest path node's travel) or the whole background grid ('full').",
)
improve_option = click.option(
    "--improve/--no-improve",
    default=True,
    show_default=True,
    help="Better triangles: around every triangle under 35 degrees, flip edges, move "
    "free nodes and, where that cannot help (a thin part, a sharp corner), re-mesh a "
    "few triangles around one node, while the smallest angle grows (boundary nodes "
    "never move).",
)
format_option = click.option(
    "--format",
    "fmt",
    type=click.Choice(sorted(formats.FORMATS), case_sensitive=False),
    default=None,
    help="Mesh format. Default: from the output file's extension.",
)
msh_option = click.option(
    "--msh-version",
    type=click.Choice(sorted(formats.MSH_VERSIONS)),
    default="2.2",
    show_default=True,
    help="Gmsh file version for .msh output (ASCII either way).",
)
quiet_option = click.option("-q", "--quiet", is_flag=True, help="Print errors only.")
png_option = click.option(
    "--png",
    type=click.Path(dir_okay=False),
    default=None,
    help="Also draw the mesh to this PNG file (needs matplotlib).",
)


def _apply(options):
    def deco(fn):
        for opt in reversed(options):
            fn = opt(fn)
        return fn

    return deco


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="deformesh")
def cli():
    """Triangle meshes whose boundary nodes are exactly your contour's points.

    A Cartesian grid is deformed onto the contour by a div-curl system
    (Liao et al.), so the interior stays structured and never folds.
    """


@cli.command("select")
@click.argument("contour", type=click.Path(dir_okay=False, allow_dash=True))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(dir_okay=False, allow_dash=True),
    help="State file to write ('-' for stdout).",
)
@_apply(select_options)
@quiet_option
@_handle_errors
def select_cmd(
    contour,
    output,
    h,
    box,
    margin,
    strict,
    max_nodes,
    decimal,
    tolerance,
    element_id,
    resample,
    exterior,
    grid,
    quiet,
):
    """Lay the background grid and pick one grid node per contour point (stage 1)."""
    _check_binary_stdout(output)
    c = _read_contour(contour, decimal, tolerance, element_id, resample)
    sel = pipeline.run_select(c, h, box, margin, strict, max_nodes, exterior, grid)
    files.write_bytes(state.dumps(state.State("selected", c, sel)), output)
    g = sel.grid
    _say(
        quiet,
        f"{c.source}: selected {c.n} grid nodes on a {g.nx}x{g.ny} grid "
        f"(h = {sel.h:.4g}), {sel.extra_nodes} extra boundary nodes",
    )


@cli.command("deform")
@click.argument("state_in", metavar="STATE", type=click.Path(dir_okay=False, allow_dash=True))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(dir_okay=False, allow_dash=True),
    help="Deformed state file to write ('-' for stdout).",
)
@steps_option
@solver_option
@solve_option
@_apply(size_options)
@quiet_option
@_handle_errors
def deform_cmd(state_in, output, steps, solver, solve, size_expr, size_field, quiet):
    """Move the selected nodes onto the contour without folding (stage 2)."""
    _check_binary_stdout(output)
    name = "<stdin>" if state_in == "-" else state_in
    st = state.loads(files.read_bytes(state_in), name, want="selected")
    size = _size.make(size_expr, size_field, st.contour)
    with _steps_bar(steps, quiet) as progress:
        d = pipeline.run_deform(
            st.contour,
            st.selection,
            steps,
            callback=progress,
            solver=solver,
            size=size,
            solve=solve,
        )
    meta = {"steps": steps}
    if size is not None:
        meta.update(size=size_expr, size_field=size_field)
    out = state.State("deformed", st.contour, st.selection, d.points, meta)
    files.write_bytes(state.dumps(out), output)
    _say(
        quiet,
        f"{st.contour.source}: deformed in {d.stats.solves} solves "
        f"({d.stats.halvings} step halvings)",
    )


@cli.command("triangulate")
@click.argument("state_in", metavar="STATE", type=click.Path(dir_okay=False, allow_dash=True))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(dir_okay=False, allow_dash=True),
    help="Mesh file to write; the format follows the extension.",
)
@improve_option
@format_option
@msh_option
@png_option
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON on stdout.")
@quiet_option
@_handle_errors
def triangulate_cmd(state_in, output, improve, fmt, msh_version, png, as_json, quiet):
    """Keep the triangles inside the contour and write the mesh (stage 3)."""
    t0 = time.perf_counter()
    fmt = _check_mesh_output(output, fmt, as_json)
    name = "<stdin>" if state_in == "-" else state_in
    st = state.loads(files.read_bytes(state_in), name, want="deformed")
    size = (
        _size.make(st.meta.get("size"), st.meta.get("size_field"), st.contour) if st.meta else None
    )
    mesh, report = pipeline.run_triangulate(
        st.contour, pipeline.Deformed(st.selection, st.points), size, improve=improve
    )
    report.update(pipeline.selection_report(st.selection))
    _finish(st.contour, mesh, report, output, fmt, as_json, quiet, t0, msh_version, png)


def _check_mesh_output(output, fmt, as_json):
    if as_json and output == "-":
        raise click.UsageError("--json and -o - both use stdout; write the mesh to a file")
    return formats.format_for(output, fmt)  # an OptionError is a usage error (_handle_errors)


def _finish(contour, mesh, report, output, fmt, as_json, quiet, t0, msh_version="2.2", png=None):
    picture = None
    if png is not None:  # drawn first: a failure here leaves no mesh file either
        from . import plot

        files.check_folder(png)
        picture = plot.render(
            mesh.points,
            mesh.triangles,
            boundary=mesh.lines,
            contour_points=mesh.points[: mesh.n_contour],
            title=_title(output, mesh),
        )
    formats.write_mesh(mesh, output, fmt, msh_version)
    if picture is not None:
        files.write_bytes(picture, png)
    report = {
        "input": contour.source,
        "output": output,
        "format": fmt,
        **report,
        "seconds": round(time.perf_counter() - t0, 3),
    }
    report["notes"] = list(contour.notes) + list(report.get("notes", []))
    if as_json:
        click.echo(json.dumps(report, sort_keys=False))
    for note in report["notes"]:
        _say(quiet, f"note: {contour.source}: {note}")
    _say(quiet, summary_line(report))


def summary_line(r: dict) -> str:
    return (
        f"{r['input']} -> {r['output']}: {r['nodes']} nodes, {r['triangles']} triangles, "
        f"angles {r['min_angle']:.1f}-{r['max_angle']:.1f} deg, smallest area "
        f"{r['smallest_area']:.3g}, {r['extra_boundary_nodes']} extra boundary nodes, "
        f"contract {r['contract']} ({r['seconds']:.2f} s)"
    )


@cli.command("all")
@click.argument(
    "contours", metavar="CONTOUR...", nargs=-1, required=True, type=click.Path(allow_dash=True)
)
@click.option(
    "-o",
    "--output",
    default=None,
    type=click.Path(dir_okay=False, allow_dash=True),
    help="Mesh file to write (one contour); the format follows the extension.",
)
@click.option(
    "--out-dir",
    default=None,
    type=click.Path(file_okay=False),
    help="Batch: write each contour's mesh here as NAME.FORMAT (created if missing). "
    "CONTOUR may then be several files, folders and glob patterns.",
)
@click.option(
    "-j",
    "--jobs",
    type=click.IntRange(min=1),
    default=None,
    help="Batch: processes to run at once. Default: the number of cores.",
)
@click.option(
    "--scheduler",
    default=None,
    metavar="ADDRESS",
    help="Batch: run on a Dask distributed cluster (e.g. tcp://host:8786); needs deformesh[dask].",
)
@click.option("--fail-fast", is_flag=True, help="Batch: stop at the first failure.")
@_apply(select_options)
@steps_option
@solver_option
@solve_option
@_apply(size_options)
@improve_option
@format_option
@msh_option
@png_option
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print the summary as JSON on stdout (a batch: one record per contour).",
)
@quiet_option
@_handle_errors
def all_cmd(
    contours,
    output,
    out_dir,
    jobs,
    scheduler,
    fail_fast,
    h,
    box,
    margin,
    strict,
    max_nodes,
    decimal,
    tolerance,
    element_id,
    resample,
    exterior,
    grid,
    steps,
    solver,
    solve,
    size_expr,
    size_field,
    improve,
    fmt,
    msh_version,
    png,
    as_json,
    quiet,
):
    """Run select, deform and triangulate in one process, for one contour or a batch."""
    t0 = time.perf_counter()
    if out_dir is not None:
        if output is not None:
            raise click.UsageError(
                "give -o FILE (one contour) or --out-dir DIR (a batch), not both"
            )
        if png is not None:
            raise click.UsageError("--png names one file; it does not apply to a batch")
        options = {
            "h": h,
            "box": box,
            "margin": margin,
            "strict": strict,
            "max_nodes": max_nodes,
            "decimal": decimal,
            "tolerance": tolerance,
            "element_id": element_id,
            "resample": resample,
            "exterior": exterior,
            "grid": grid,
            "steps": steps,
            "solver": solver,
            "solve": solve,
            "msh_version": msh_version,
            "size": size_expr,
            "size_field": size_field,
            "improve": improve,
        }
        _batch(
            list(contours), out_dir, fmt, options, jobs, scheduler, fail_fast, as_json, quiet, t0
        )
        return
    if output is None:
        raise click.UsageError("give -o FILE (one contour) or --out-dir DIR (a batch)")
    if len(contours) != 1 or (contours[0] != "-" and os.path.isdir(contours[0])):
        raise click.UsageError("several contours or a folder need --out-dir DIR instead of -o")
    if jobs is not None or scheduler is not None or fail_fast:
        raise click.UsageError("--jobs, --scheduler and --fail-fast apply to batches (--out-dir)")
    fmt = _check_mesh_output(output, fmt, as_json)
    c = _read_contour(contours[0], decimal, tolerance, element_id, resample)
    size = _size.make(size_expr, size_field, c)
    with _steps_bar(steps, quiet) as progress:
        res = pipeline.mesh_contour(
            c,
            h,
            box,
            margin,
            strict,
            max_nodes,
            steps,
            solver=solver,
            exterior=exterior,
            callback=progress,
            size=size,
            grid=grid,
            solve=solve,
            improve=improve,
        )
    _finish(c, res.mesh, res.report, output, fmt, as_json, quiet, t0, msh_version, png)


def _show_progress(quiet: bool) -> bool:
    """Progress bars only for a person watching: stderr is a terminal and not --quiet."""
    return not quiet and sys.stderr.isatty()


@contextlib.contextmanager
def _steps_bar(steps: int, quiet: bool):
    """A deformation progress callback drawing a bar on stderr (or doing nothing)."""
    if not _show_progress(quiet):
        yield None
        return
    with click.progressbar(length=1000, label="deforming", file=sys.stderr) as bar:

        def progress(done, stats):
            bar.update(int(1000 * done) - bar.pos)

        yield progress


def _batch(contours, out_dir, fmt, options, jobs, scheduler, fail_fast, as_json, quiet, t0):
    fmt = formats.format_for(f"x.{fmt or 'msh'}", None)
    # usage errors before any work, not once per input
    _size.check_options(options.get("size"), options.get("size_field"))
    tasks = batch.make_tasks(batch.expand_inputs(contours), out_dir, fmt, options)
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:
        raise DeformeshError(
            f"{out_dir}: cannot create the output folder: {exc.strerror}"
        ) from None
    records: list[dict | None] = [None] * len(tasks)
    printed = 0
    bar = None
    if _show_progress(quiet) and len(tasks) > 1:
        bar = click.progressbar(length=len(tasks), label="meshing", file=sys.stderr)
        bar.__enter__()
    try:
        for task, rec, outputs in batch.run(
            tasks, jobs or os.cpu_count() or 1, scheduler, fail_fast
        ):
            if rec["status"] == "ok":
                try:
                    files.write_files(out_dir, outputs)
                except DeformeshError as exc:
                    rec.update(status="failed", error=str(exc))
            if rec["status"] == "failed":  # over the progress bar's line, if one is drawn
                clear = "\r\033[K" if bar is not None else ""
                click.echo(f"{clear}deformesh: error: {rec['error']}", err=True)
            records[task.index] = rec
            while printed < len(records) and records[printed] is not None:
                if as_json:
                    click.echo(json.dumps(records[printed]))
                printed += 1
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
    if not quiet:
        click.echo(batch_table(records, time.perf_counter() - t0), err=True)
    if any(r["status"] != "ok" for r in records):
        sys.exit(1)


def batch_table(records: list[dict], seconds: float) -> str:
    """The end-of-batch summary: a count line, then one row per input."""
    ok = sum(r["status"] == "ok" for r in records)
    failed = sum(r["status"] == "failed" for r in records)
    skipped = len(records) - ok - failed
    head = f"deformesh: {len(records)} contour(s): {ok} ok, {failed} failed"
    head += f", {skipped} skipped" if skipped else ""
    rows = [
        head + f" ({seconds:.2f} s)",
        f"  {'status':8} {'nodes':>8} {'triangles':>9} {'min angle':>9} {'seconds':>8}  input",
    ]
    for r in records:
        if r["status"] == "ok":
            nums = (
                f"{r['nodes']:>8} {r['triangles']:>9} {r['min_angle']:>9.1f} {r['seconds']:>8.2f}"
            )
            rows.append(f"  {'ok':8} {nums}  {r['input']}")
        else:
            why = r["error"].removeprefix(f"{r['input']}: ")
            rows.append(
                f"  {r['status']:8} {'-':>8} {'-':>9} {'-':>9} {r['seconds']:>8.2f}  "
                f"{r['input']}: {why}"
            )
    return "\n".join(rows)


def _title(name, mesh) -> str:
    return f"{name}: {mesh.n_nodes} nodes, {len(mesh.triangles)} triangles"


@cli.command("move")
@click.argument("mesh_path", metavar="MESH", type=click.Path(dir_okay=False))
@click.argument(
    "frames", metavar="FRAME...", nargs=-1, required=True, type=click.Path(dir_okay=False)
)
@click.option(
    "--out-dir",
    required=True,
    type=click.Path(file_okay=False),
    help="Write the frames here as NAME_0000.FORMAT, ... (created if missing), "
    "and NAME.pvd, the time series ParaView opens (.vtu only).",
)
@click.option("--name", default=None, help="File name stem.  Default: MESH's.")
@click.option(
    "--dt",
    type=float,
    default=1.0,
    show_default=True,
    callback=_positive,
    help="Time between frames: the .pvd's time step; velocity = displacement / dt.",
)
@steps_option
@solver_option
@click.option(
    "--solve",
    type=click.Choice(pipeline.SOLVES),
    default="full",
    show_default=True,
    help="Solve on the whole mesh ('full', the paper's scheme) or, on an exterior "
    "mesh, on a band around the contour ('band': faster, but changes of shape "
    "pile up at the band's edge).",
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(sorted(formats.FORMATS), case_sensitive=False),
    default="vtu",
    show_default=True,
    help="Frame format.  Velocity is written where the format has point data (vtu, vtk, xdmf).",
)
@click.option(
    "--decimal",
    type=click.Choice([".", ","]),
    default=".",
    show_default=True,
    help="Decimal mark of the frames' CSV numbers.",
)
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON on stdout.")
@quiet_option
@_handle_errors
def move_cmd(
    mesh_path, frames, out_dir, name, dt, steps, solver, solve, fmt, decimal, as_json, quiet
):
    """Carry a mesh along as its contour moves: one file per FRAME, same triangles.

    MESH is a mesh deformesh wrote (its nodes 0..m-1 are the contour points in
    order); each FRAME is a contour of the same m points, point k following
    point k.  Each frame's mesh is the previous one deformed (the div-curl
    scheme over pseudo-time, contour nodes to the frame's points, box nodes
    held), checked for folds at every step.  Frame 0 is MESH itself.
    """
    import numpy as np

    from . import move
    from .errors import FoldError

    t0 = time.perf_counter()
    fmt = fmt.lower()
    stem = name or os.path.splitext(os.path.basename(mesh_path))[0]
    points, tri = formats.read_mesh(mesh_path)
    contours = [_read_contour(f, decimal) for f in frames]  # every frame read first:
    motion = move.prepare(points, tri, contours[0], mesh_path)
    for c in contours[1:]:  # a bad one fails before any work
        move.check_frame(motion, c)
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:
        raise DeformeshError(
            f"{out_dir}: cannot create the output folder: {exc.strerror}"
        ) from None
    width = max(4, len(str(len(frames))))
    written: list[tuple[float, str]] = []
    records = []

    def write(k, pts, velocity, source, report):
        mesh = move.frame_mesh(motion, pts, {"velocity": velocity})
        file = f"{stem}_{k:0{width}d}.{fmt}"
        formats.write_mesh(mesh, os.path.join(out_dir, file), fmt)
        written.append((k * dt, file))
        records.append({"frame": k, "input": source, "output": file, **report})

    def finish():  # the time series of the frames written so far
        if fmt == "vtu" and written:
            files.write_bytes(formats.pvd_bytes(written), os.path.join(out_dir, f"{stem}.pvd"))

    zero = np.zeros((len(points), 3))
    write(0, motion.mesh.points, zero, mesh_path, quality.stats(motion.mesh))
    pts = motion.mesh.points
    advice = (
        "the frame's points cannot be reached from the previous frame's without folding",
        "use more --steps, or frames closer together",
    )
    try:
        for k, c in enumerate(contours, start=1):
            try:
                step = move.advance(motion, pts, c, steps, solver, solve, advice=advice)
            except FoldError as exc:
                raise DeformeshError(
                    f"{c.source}: frame {k} of {len(contours)} cannot be reached without "
                    f"folding: {exc}; frames 0-{k - 1} are in {out_dir}"
                ) from None
            velocity = np.column_stack([(step.points - pts) / dt, np.zeros(len(pts))])
            write(k, step.points, velocity, c.source, step.report)
            pts = step.points
            r = records[-1]
            _say(
                quiet,
                f"frame {k}/{len(contours)} {c.source}: min angle "
                f"{r['min_angle']:.1f} deg, {r['solves']} solves, "
                f"{r['halvings']} step halvings",
            )
    finally:
        finish()
    first = records[0]["min_angle"]
    lowest = min(records, key=lambda r: r["min_angle"])
    worst = lowest["min_angle"]
    summary = {
        "mesh": mesh_path,
        "out_dir": out_dir,
        "format": fmt,
        "pvd": f"{stem}.pvd" if fmt == "vtu" else None,
        "frames": len(records),
        "nodes": records[0]["nodes"],
        "triangles": records[0]["triangles"],
        "min_angle": worst,
        "min_angle_first": first,
        "min_angle_frame": int(lowest["frame"]),
        "seconds": round(time.perf_counter() - t0, 3),
        "per_frame": records,
    }
    if as_json:
        click.echo(json.dumps(summary))
    if fmt not in formats.POINT_DATA_FORMATS:
        _say(quiet, f"note: .{fmt} has no point data: the velocity is not written")
    _say(
        quiet,
        f"{len(records)} frames -> {out_dir}"
        f"{'/' + summary['pvd'] if summary['pvd'] else ''}: same {len(tri)} triangles "
        f"in every frame, min angle {worst:.1f} deg over all frames (frame 0: "
        f"{first:.1f}) ({summary['seconds']:.2f} s)",
    )


@cli.command("quality")
@click.argument("mesh_path", metavar="MESH", type=click.Path(dir_okay=False))
@click.option(
    "--contour",
    "contour_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Check the mesh contract against this contour (the file it was made from).",
)
@_apply(contour_options)
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@_handle_errors
def quality_cmd(mesh_path, contour_path, decimal, tolerance, element_id, resample, as_json):
    """Report a mesh's angles, areas and radius ratios; check the contract against a contour.

    Exit 1 if a triangle is folded or (with --contour) the contract is broken.
    """
    points, tri = formats.read_mesh(mesh_path)
    c = None
    if contour_path is not None:
        c = _read_contour(contour_path, decimal, tolerance, element_id, resample)
    rep, problem = quality.assess(points, tri, c)
    rep = {"mesh": mesh_path, **rep}
    if as_json:
        click.echo(json.dumps(rep))
    else:
        click.echo(quality_text(rep))
    if problem:
        click.echo(f"deformesh: error: {mesh_path}: {problem}", err=True)
        sys.exit(1)


def quality_text(r: dict) -> str:
    x, y = r["smallest_area_at"]
    out = [
        f"{r['mesh']}: {r['nodes']} nodes, {r['triangles']} triangles, area {r['area']:.6g}",
        f"angles: min {r['min_angle']:.2f} deg, max {r['max_angle']:.2f} deg; "
        f"{r['angles_below_20']} triangle(s) with an angle below 20 deg",
        f"smallest signed area: {r['smallest_area']:.3g} at ({x:.6g}, {y:.6g}); "
        f"folded: {r['folded']}",
        f"radius ratio 2r/R: mean {r['mean_radius_ratio']:.3f}, min {r['min_radius_ratio']:.3f}",
    ]
    h = r["radius_ratio_histogram"]
    top = max(h["counts"]) or 1
    for lo, hi, k in zip(h["edges"], h["edges"][1:], h["counts"]):
        out.append(f"  {lo:.1f}-{hi:.1f} {k:9d} {'#' * round(40 * k / top)}".rstrip())
    out.append(f"contract: {r['contract']}")
    return "\n".join(out)


@cli.command("plot")
@click.argument("mesh_path", metavar="MESH", type=click.Path(dir_okay=False))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(dir_okay=False, allow_dash=True),
    help="PNG file to write ('-' for stdout).",
)
@click.option(
    "--contour",
    "contour_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Draw this contour's points over the mesh.",
)
@_apply(contour_options)
@_handle_errors
def plot_cmd(mesh_path, output, contour_path, decimal, tolerance, element_id, resample):
    """Draw a mesh to PNG: triangles shaded by radius ratio, the boundary, a histogram."""
    from . import plot

    _check_binary_stdout(output)
    points, tri = formats.read_mesh(mesh_path)
    cpts = None
    if contour_path is not None:
        cpts = _read_contour(contour_path, decimal, tolerance, element_id, resample).points
    plot.draw(
        points,
        tri,
        output,
        contour_points=cpts,
        title=f"{mesh_path}: {len(points)} nodes, {len(tri)} triangles",
    )


def main() -> None:
    """Entry point: run the CLI; a closed downstream pipe ends quietly."""
    try:
        cli.main(prog_name="deformesh", standalone_mode=True)
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        sys.exit(1)


if __name__ == "__main__":  # pragma: no cover
    main()
