"""Batch meshing: many contours, one record per input, a process pool or a Dask cluster.

The caller reads every input (:func:`make_tasks`), the workers mesh them
(:func:`run_task`: contour bytes in, a record and the output files' bytes
out, nothing touches the disk), and the caller writes each input's files as
they arrive.  So a worker needs no shared file system, one input's failure
never leaves a file behind, and the bytes do not depend on where or in what
order the inputs ran.  Nothing here prints or exits.
"""

from __future__ import annotations

import concurrent.futures as cf
import glob
import os
import stat
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from . import files, formats
from . import size as _size
from .errors import OUT_OF_MEMORY, DeformeshError, OptionError
from .options import MeshOptions
from .readers import load_contour

#: What a folder given as input contributes: files with these extensions (every contour
#: format :func:`.readers.load_contour` reads).  Its other files (but hidden ones) are
#: listed as not meshed, and with ``strict_inputs`` fail the batch.
CONTOUR_SUFFIXES = (".csv", ".txt", ".svg", ".svgz", ".geojson", ".json")

#: Keys of every batch record (``--json`` prints one per input, in input order).
RECORD_KEYS = (
    "input",
    "output",
    "status",
    "error",
    "seconds",
    "nodes",
    "triangles",
    "min_angle",
    "extra_boundary_nodes",
    "contract",
)


@dataclass(frozen=True)
class Task:
    """One input: where it came from, what it holds, where its mesh goes, how to mesh it."""

    index: int
    source: str
    output: str
    data: bytes | None = None
    error: str | None = None  # reading failed: nothing to run
    options: MeshOptions = field(default_factory=MeshOptions)
    passed: str | None = None  # a folder's file that is no contour file: not run, and why


def expand_inputs(args: list[str]) -> list[tuple[str, str | None]]:
    """``(file, why it is passed over or None)``: files as given, folders' files (sorted;
    those without a contour extension, :data:`CONTOUR_SUFFIXES`, passed over, hidden
    ones left out), and glob patterns (sorted).

    A pattern that matches nothing is kept, so that it is reported as missing.
    """
    out: list[tuple[str, str | None]] = []
    for a in args:
        p = Path(a)
        if a != "-" and p.is_dir():
            # every entry but hidden ones and folders: one that is no regular file (a
            # pipe, a device, a link to nothing) is named, never read, never dropped
            found = sorted(q for q in p.iterdir() if not q.name.startswith(".") and not q.is_dir())
            if not any(q.suffix.lower() in CONTOUR_SUFFIXES for q in found):
                raise OptionError(
                    f"{a}: folder holds no contour files ({', '.join(CONTOUR_SUFFIXES)})"
                )
            out += [(str(q), _passed_over(q)) for q in found]
        elif a != "-" and not os.path.lexists(a) and any(ch in a for ch in "*?["):
            matches = sorted(f for f in glob.glob(a) if not os.path.isdir(f))
            out += [(f, None) for f in matches or [a]]
        else:
            out.append((a, None))
    return out


def not_regular(path: str) -> str | None:
    """Why a file a folder or a pattern found is not read: it is no regular file (a
    pipe would wait for a writer forever, a device never ends, a link leads nowhere);
    None for a regular file."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return f"{path}: is a symbolic link that leads to no file (dangling, or a loop)"
    if stat.S_ISREG(mode):
        return None
    return f"{path}: is not a regular file (a pipe, a device or a socket); it is not read"


def _passed_over(path: Path) -> str | None:
    """Why a folder's file is not meshed (no contour extension), or None."""
    if path.suffix.lower() in CONTOUR_SUFFIXES:
        return None
    kind = f"{path.suffix} is not" if path.suffix else "no extension is"
    known = ", ".join(CONTOUR_SUFFIXES)
    return f"{path}: not meshed: {kind} a contour file's extension ({known})"


def prepare(
    inputs: list[str],
    out_dir: str,
    options: MeshOptions,
    force: bool = False,
    strict_inputs: bool = False,
) -> list[Task]:
    """Everything before the work: the inputs expanded and read, the output format and
    size function checked (usage errors before any work, not once per input), the
    outputs checked (none is an input, a link, or a sidecar deformesh did not write,
    unless ``force``), then the output folder created.  A folder's file that is no
    contour file is passed over, or with ``strict_inputs`` fails."""
    fmt = formats.format_for(f"x.{options.fmt or 'msh'}", None)
    _size.check_options(options.size, options.size_field)
    found = expand_inputs(inputs)
    named = set(inputs)  # (a pipe named on the command line is read: <(command))
    unread = {
        f: why for f, over in found if over is None and f not in named and (why := not_regular(f))
    }
    if strict_inputs:  # (each is then a failed input, not one passed over)
        passed = {}
        errors = {f: why.replace(": not meshed: ", ": ") for f, why in found if why}
    else:
        passed = {f: why for f, why in found if why}
        errors = {}
    errors.update(unread)  # (a contour file's name: it fails, named, and is never read)
    tasks = make_tasks([f for f, _ in found], out_dir, options.replace(fmt=fmt), passed, errors)
    inputs = [t.source for t in tasks] + [options.size_field]
    outputs = [t.output for t in tasks if t.output]  # (a file passed over or failed names none)
    formats.check_outputs(outputs, fmt, inputs, typed=False, force=force)
    files.make_folder(out_dir)
    return tasks


def make_tasks(
    inputs: list[str],
    out_dir: str,
    options: MeshOptions,
    passed: dict[str, str] | None = None,
    errors: dict[str, str] | None = None,
) -> list[Task]:
    """Read every input (a failure becomes the task's error) and name its output
    ``out_dir/NAME.FORMAT`` (``options.fmt``); ``passed``: inputs not to mesh, and
    why (they read nothing and name no output); ``errors``: inputs that fail, and why.

    Two inputs that would write the same output file are a usage error.
    """
    passed, errors = passed or {}, errors or {}
    outputs: dict[str, str] = {}
    tasks = []
    for k, src in enumerate(inputs):
        if src in passed:
            tasks.append(Task(k, src, "", passed=passed[src], options=options))
            continue
        if src in errors:
            tasks.append(Task(k, src, "", error=errors[src], options=options))
            continue
        stem = "stdin" if src == "-" else Path(src).name.split(".")[0] or f"input_{k}"
        out = str(Path(out_dir) / f"{stem}.{options.fmt}")
        if out in outputs:
            raise OptionError(
                f"{outputs[out]} and {src} would both write {out}; "
                "rename one or mesh them in two runs"
            )
        outputs[out] = src
        data, error = None, None
        try:
            data = files.read_bytes(src)
        except DeformeshError as exc:
            error = str(exc)
        tasks.append(Task(k, src, out, data, error, options))
    return tasks


def run_task(task: Task) -> tuple[dict, list[tuple[str, bytes]]]:
    """Mesh one input in memory: ``(record, [(file name, bytes), ...])``; never raises."""
    from .pipeline import mesh_contour

    t0 = time.perf_counter()
    o = task.options
    rec = _record(task, "failed")
    outputs: list[tuple[str, bytes]] = []
    try:
        if task.error is not None:
            raise DeformeshError(task.error)
        c = load_contour(
            task.source, task.data, o.decimal, o.tolerance, o.element_id, o.resample, o.stroke
        )
        res = mesh_contour(c, o)
        outputs = formats.mesh_files(res.mesh, Path(task.output).name, o.fmt, o.msh_version)
        r = res.report
        rec.update(
            status="ok",
            nodes=r["nodes"],
            triangles=r["triangles"],
            min_angle=r["min_angle"],
            extra_boundary_nodes=r["extra_boundary_nodes"],
            contract=r["contract"],
        )
    except DeformeshError as exc:
        rec["error"] = str(exc)
    except MemoryError:
        rec["error"] = f"{task.source}: {OUT_OF_MEMORY}"
    except Exception as exc:  # a bug of ours: report it and keep the batch going
        rec["error"] = f"{task.source}: internal error: {type(exc).__name__}: {exc}"
    rec["seconds"] = round(time.perf_counter() - t0, 3)
    return rec, outputs


def run_and_write(
    tasks: list[Task],
    out_dir: str,
    jobs: int = 1,
    scheduler: str | None = None,
    fail_fast: bool = False,
) -> Iterator[tuple[Task, dict]]:
    """:func:`run`, writing each input's files into ``out_dir`` as they arrive (atomically;
    if one cannot be written, none of that input's stays and its record says why)."""
    for task, rec, outputs in run(tasks, jobs, scheduler, fail_fast):
        if rec["status"] == "ok":
            try:
                files.write_files(out_dir, outputs)
            except DeformeshError as exc:
                rec.update(status="failed", error=str(exc))
        yield task, rec


def run(
    tasks: list[Task], jobs: int = 1, scheduler: str | None = None, fail_fast: bool = False
) -> Iterator[tuple[Task, dict, list]]:
    """Run every task; yield ``(task, record, files)`` as each finishes.

    ``jobs`` > 1 uses a process pool; ``scheduler`` a Dask distributed cluster.
    With ``fail_fast`` the first failure stops the rest: tasks not finished
    are yielded as ``skipped``.  Tasks passed over (``Task.passed``) come first, as
    ``skipped``, with why.
    """
    for t in tasks:
        if t.passed is not None:
            yield t, _record(t, "skipped", t.passed), []
    tasks = [t for t in tasks if t.passed is None]
    if scheduler is not None:
        yield from _run_dask(tasks, scheduler, fail_fast)
        return
    if jobs <= 1 or len(tasks) <= 1:
        for k, t in enumerate(tasks):
            rec, files = run_task(t)
            yield t, rec, files
            if fail_fast and rec["status"] != "ok":
                yield from _skipped(tasks[k + 1 :])
                return
        return
    yield from _run_pool(tasks, jobs, fail_fast)


def _run_pool(tasks: list[Task], jobs: int, fail_fast: bool) -> Iterator:
    """A process pool.  A worker that dies (killed, out of memory) breaks the whole pool:
    the tasks it took down with it are run again one by one, each in a pool of its own,
    so only the one that kills its worker fails."""
    broken: list[Task] = []
    failed = False
    with cf.ProcessPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(run_task, t): t for t in tasks}
        for t, rec, files in _gather(
            futures,
            cf.as_completed(futures),
            fail_fast,
            cancel=lambda: pool.shutdown(wait=False, cancel_futures=True),
        ):
            if rec.pop("_broken", False):
                broken.append(t)
                continue
            failed |= rec["status"] != "ok"
            yield t, rec, files
    broken.sort(key=lambda u: u.index)
    for k, t in enumerate(broken):
        if fail_fast and failed:
            yield from _skipped(broken[k:])
            return
        with cf.ProcessPoolExecutor(max_workers=1) as alone:
            fut = alone.submit(run_task, t)
            t, rec, files = next(_gather({fut: t}, [fut], False, cancel=None))
        rec.pop("_broken", None)
        failed |= rec["status"] != "ok"
        yield t, rec, files


def _gather(futures: dict, completed, fail_fast: bool, cancel) -> Iterator:
    """Yield each future's ``(task, record, files)``; a dead worker is a failed record
    (marked ``_broken`` if it took a process pool down).  With ``fail_fast`` the first
    failure cancels the rest, which are yielded as skipped."""
    done = set()
    for fut in completed:
        t = futures[fut]
        try:
            rec, files = fut.result()
        except Exception as exc:  # the worker died (killed, out of memory, lost)
            rec, files = (
                _record(
                    t,
                    "failed",
                    f"{t.source}: the worker process running it "
                    f"died ({type(exc).__name__}; killed or out of memory?)",
                ),
                [],
            )
            if isinstance(exc, cf.process.BrokenProcessPool):
                rec["_broken"] = True
        done.add(t.index)
        yield t, rec, files
        if fail_fast and rec["status"] != "ok" and not rec.get("_broken"):
            cancel()
            yield from _skipped([u for u in futures.values() if u.index not in done])
            return


def _skipped(tasks: list[Task]) -> Iterator:
    for t in tasks:
        yield t, _record(t, "skipped", f"{t.source}: not run (--fail-fast after a failure)"), []


def _record(t: Task, status: str, error: str | None = None) -> dict:
    """A record with every key of :data:`RECORD_KEYS`, the mesh numbers still empty."""
    rec = dict.fromkeys(RECORD_KEYS)
    rec.update(input=t.source, output=t.output or None, status=status, error=error, seconds=0.0)
    return rec


def _run_dask(tasks: list[Task], scheduler: str, fail_fast: bool) -> Iterator:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise DeformeshError(
            "--scheduler needs dask.distributed: pip install 'deformesh[dask]'"
        ) from None
    try:
        client = Client(scheduler, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise DeformeshError(f"--scheduler {scheduler}: cannot connect: {exc}") from None
    with client:
        futs = client.map(run_task, tasks, pure=False)
        futures = dict(zip(futs, tasks))
        yield from _gather(
            futures, as_completed(futs), fail_fast, cancel=lambda: client.cancel(futs)
        )
