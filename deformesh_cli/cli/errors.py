"""The one place where core errors become exit codes and one-line messages.

:class:`~deformesh_cli.errors.OptionError` is a usage error (exit 2); every
other :class:`~deformesh_cli.errors.DeformeshError` is a processing failure
(exit 1, ``deformesh: error: ...`` on stderr); so is running out of memory.
Nothing else is caught: anything else is a bug, and its traceback is wanted.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable

import click

from ..errors import OUT_OF_MEMORY, DeformeshError, OptionError, one_line


def fail(message: str) -> None:
    """Print ``deformesh: error: message`` on stderr (one line: control characters
    escaped) and exit 1."""
    click.echo(f"deformesh: error: {one_line(message)}", err=True)
    sys.exit(1)


def handle_errors(fn: Callable) -> Callable:
    """Run a command; core errors become their exit codes, never a traceback."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except OptionError as exc:
            raise click.UsageError(one_line(str(exc))) from None
        except DeformeshError as exc:
            fail(str(exc))
        except MemoryError:
            fail(OUT_OF_MEMORY)

    return wrapper
