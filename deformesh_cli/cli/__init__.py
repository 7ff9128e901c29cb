"""The command line: click only.

One module per subcommand (a command parses, calls the core, reports);
:mod:`.options` builds the click options from :mod:`deformesh_cli.options`;
:mod:`.errors` is the one place where core errors become exit codes.
stdout carries data only (a state file, a mesh, ``--json``); messages go to
stderr.  Exit codes: 0 ok, 1 processing failure, 2 usage error.
"""

from __future__ import annotations

import os
import sys
import warnings

import click

from .. import __version__
from . import adapt, deform, move, plot, quality, select, triangulate
from . import all as all_command


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="deformesh")
def cli():
    """Triangle meshes whose boundary nodes are exactly your contour's points.

    A Cartesian grid is deformed onto the contour by a div-curl system
    (Liao et al.), so the interior stays structured and never folds.
    """


for _module in (select, deform, triangulate, all_command, move, adapt, quality, plot):
    cli.add_command(_module.command)


def _no_huge_pages() -> None:
    """numpy's huge-page advice off for this process, unless ``NUMPY_MADVISE_HUGEPAGE``
    says otherwise: where the kernel compacts memory at the page fault (transparent huge
    pages on "madvise"), it costs more than it saves, and the bytes are the same either
    way (benchmarks/MEASURED.md).  The command's own process only: importing the
    package changes nothing (batch workers are forked from it and inherit it)."""
    if "NUMPY_MADVISE_HUGEPAGE" in os.environ:
        return
    try:
        from numpy._core import multiarray
    except ImportError:  # (numpy before 2)
        from numpy.core import multiarray

    setter = getattr(multiarray, "_set_madvise_hugepage", None)
    if setter is not None:
        setter(False)


def main() -> None:
    """Entry point: run the CLI; a closed downstream pipe ends quietly.

    A stdout closed at start (``>&-``) is held on ``/dev/null``, so no file the run
    opens takes its descriptor; writing data there is still refused (``sys.stdout``
    stays None).  No warning is printed.  Bytes a failed stdout kept are dropped at
    exit, where flushing them again would print a second message."""
    if sys.stdout is None:
        os.open(os.devnull, os.O_WRONLY)  # (the lowest free descriptor: 1)
    # every message is one line: a library's warning (numpy's RuntimeWarning, two
    # lines) is never printed (the hostile-input tests run the commands in-process with
    # warnings as errors, so none hides there)
    warnings.simplefilter("ignore")
    _no_huge_pages()
    try:
        cli.main(prog_name="deformesh", standalone_mode=True)
    except BrokenPipeError:
        _drop_stdout()
        sys.exit(1)
    finally:
        try:
            if sys.stdout is not None:
                sys.stdout.flush()
        except OSError:
            _drop_stdout()


def _drop_stdout() -> None:
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
