"""``deformesh all CONTOUR -o MESH`` and ``deformesh all CONTOUR... --out-dir DIR``."""

from __future__ import annotations

import os
import sys
import time

import click

from .. import batch, files, pipeline
from ..errors import one_line
from ..options import MeshOptions
from ..readers import load_contour
from . import progress
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


@click.command("all")
@click.argument(
    "contours", metavar="CONTOUR...", nargs=-1, required=True, type=click.Path(allow_dash=True)
)
@output_option(
    "Mesh file to write (one contour); the format follows the extension.", required=False
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
    type=click.IntRange(min=1, max=1024),
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
@click.option(
    "--strict-inputs",
    is_flag=True,
    help="Batch: a folder's file that is no contour file (not .csv, .txt, .svg, .svgz, "
    ".geojson or .json) fails the batch instead of being listed as not meshed.",
)
@stages("select", "read", "deform", "triangulate", "layers", "write")
@png_option
@force_option
@json_option("Print the summary as JSON on stdout (a batch: one record per contour).")
@quiet_option
@progress.progress_option
@handle_errors
def command(
    contours,
    output,
    out_dir,
    jobs,
    scheduler,
    fail_fast,
    strict_inputs,
    png,
    force,
    as_json,
    quiet,
    progress_flag,
    **kw,
):
    """Run select, deform and triangulate in one process, for one contour or a batch."""
    t0 = time.perf_counter()
    o = take(MeshOptions, kw)
    if out_dir is not None:
        if output is not None:
            raise click.UsageError(
                "give -o FILE (one contour) or --out-dir DIR (a batch), not both"
            )
        if png is not None:
            raise click.UsageError("--png names one file; it does not apply to a batch")
        tasks = batch.prepare(list(contours), out_dir, o, force, strict_inputs)
        _batch(tasks, out_dir, jobs, scheduler, fail_fast, as_json, quiet, t0, progress_flag)
        return
    if output is None:
        raise click.UsageError("give -o FILE (one contour) or --out-dir DIR (a batch)")
    if len(contours) != 1 or (contours[0] != "-" and os.path.isdir(contours[0])):
        raise click.UsageError("several contours or a folder need --out-dir DIR instead of -o")
    if jobs is not None or scheduler is not None or fail_fast or strict_inputs:
        raise click.UsageError(
            "--jobs, --scheduler, --fail-fast and --strict-inputs apply to batches (--out-dir)"
        )
    fmt = check_mesh_output(output, o.fmt, as_json)
    check_outputs(output, fmt, png, [contours[0], o.size_field], force)
    c = load_contour(contours[0], None, o.decimal, o.tolerance, o.element_id, o.resample, o.stroke)
    line = progress.LiveLine(progress.mode(quiet, progress_flag))
    name = c.source

    def on_stage(stage: str) -> None:
        line.say(f"deformesh: {name}: {stage}")

    try:
        res = pipeline.mesh_contour(c, o, callback=line.deforming(name), on_stage=on_stage)
    finally:
        line.close()
    finish(
        c,
        res.mesh,
        res.report,
        output,
        fmt,
        as_json=as_json,
        quiet=quiet,
        t0=t0,
        msh_version=o.msh_version,
        png=png,
    )


def _batch(tasks, out_dir, jobs, scheduler, fail_fast, as_json, quiet, t0, show=None) -> None:
    """Run a batch: each failure on stderr as it happens, the records in input order on
    stdout (``--json``), the table at the end; exit 1 if any input failed."""
    records: list[dict | None] = [None] * len(tasks)
    printed = 0
    bar = progress.BatchProgress(len(tasks), progress.mode(quiet, show))
    try:
        jobs = jobs or os.cpu_count() or 1
        for task, rec in batch.run_and_write(tasks, out_dir, jobs, scheduler, fail_fast):
            clear = bar.clear  # (over the live line, if one is drawn)
            if rec["status"] == "failed":
                click.echo(f"{clear}deformesh: error: {one_line(rec['error'])}", err=True)
            elif task.passed is not None and not quiet:
                click.echo(f"{clear}deformesh: {one_line(rec['error'])}", err=True)
            records[task.index] = rec
            while printed < len(records) and records[printed] is not None:
                if as_json:
                    files.write_stdout(files.to_json(records[printed]))
                printed += 1
            bar.step(rec["status"], rec["input"])
    finally:
        bar.close()
    if not quiet:
        click.echo(batch_table(records, time.perf_counter() - t0), err=True)
    if any(r["status"] == "failed" for r in records):
        sys.exit(1)


def batch_table(records: list[dict], seconds: float) -> str:
    """The end-of-batch summary: a count line, then one row per input."""
    ok = sum(r["status"] == "ok" for r in records)
    failed = sum(r["status"] == "failed" for r in records)
    skipped = len(records) - ok - failed
    head = f"deformesh: {len(records)} contour(s): {ok} ok, {failed} failed"
    head += f", {skipped} not meshed" if skipped else ""
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
    return "\n".join(map(one_line, rows))
