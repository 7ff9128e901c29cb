"""Exceptions raised by the deformesh core.

Every failure a user can act on is a :class:`DeformeshError` whose message is
one line naming the file, the problem and where.  The command-line layer
(:mod:`deformesh_cli.cli.errors`) turns them into exit codes:
:class:`OptionError` is a usage error (exit 2), every other subclass a
processing failure (exit 1).  Nothing else is meant to reach it.
"""

import contextlib
import re
from collections.abc import Iterator

#: What a run that ran out of memory is told.
OUT_OF_MEMORY = "out of memory; lower --max-nodes or give a larger --h"


class DeformeshError(Exception):
    """Base class of every error the core raises on purpose."""


class InputError(DeformeshError):
    """The contour, mesh or state file cannot be used (malformed, invalid)."""


class ReadError(InputError):
    """A file cannot be read at all (missing, a folder, no permission, not a mesh)."""


class WriteError(DeformeshError):
    """An output file cannot be written (no folder, no permission, disk full, writer failed)."""


class OptionError(DeformeshError):
    """An option value is inconsistent with the input (for example a box that misses it)."""


class SizeError(OptionError):
    """A size function fails to evaluate, or is not finite and > 0 over the box."""


class MonitorError(DeformeshError):
    """An adaptation monitor is not finite and > 0 where a mesh's nodes go (a failure
    on that mesh: the expression itself is fine)."""


class DependencyError(DeformeshError):
    """An optional dependency the request needs is not installed (the message names the extra)."""


class LimitError(DeformeshError):
    """The work would exceed a stated limit (grid nodes, memory)."""


class SelectionError(DeformeshError):
    """No simple grid path could be fitted to the contour."""


class FoldError(DeformeshError):
    """The deformation could not proceed without folding a triangle."""


class DegradedError(DeformeshError):
    """A moving mesh's frame fell under its floor on the smallest angle (``move --min-angle``)."""


class BandError(DeformeshError):
    """A node that must move lies on the edge of the narrow band: the band is too narrow."""


class SolverError(DeformeshError):
    """A linear solve of the deformation failed (an iterative solver did not converge)."""


class TimeUp(DeformeshError):
    """The search for a grid path ran past its time bound (:mod:`.deadline`)."""

    def __init__(self, seconds: float):
        super().__init__(f"no grid path found within the search's time bound of {seconds:.0f} s")
        self.seconds = seconds


class ContractError(DeformeshError):
    """A mesh does not meet the mesh contract (see docs/contract.md)."""


_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029]")


def one_line(text: str) -> str:
    """``text`` with every control character (newlines, terminal escapes) written as an
    escape (``\\n``, ``\\x1b``): what a message prints stays one line, and text from
    a file cannot drive the terminal or fake another message."""

    def escape(m: re.Match) -> str:
        c = m.group(0)
        return {"\n": "\\n", "\r": "\\r", "\t": "\\t"}.get(c) or (
            f"\\x{ord(c):02x}" if ord(c) < 256 else f"\\u{ord(c):04x}"
        )

    return _CONTROL.sub(escape, text)


def printable(text: str, limit: int = 60) -> str:
    """A value from a file, quoted, control characters escaped, cut at ``limit``."""
    text = one_line(text)
    return "'" + (text if len(text) <= limit else text[: limit - 3] + "...") + "'"


@contextlib.contextmanager
def naming(source: str | None) -> Iterator[None]:
    """A :class:`DeformeshError` raised inside that does not name ``source`` yet is
    raised again with ``source: `` in front, so every message that reaches a user names
    the file it is about (a stage deep in the construction knows points and nodes, not
    files).  Nested, a message is prefixed once."""
    try:
        yield
    except DeformeshError as exc:
        if source and source[0] != "<" and not _names_a_file(str(exc), source):
            exc.args = (f"{source}: {exc}",)
        raise


def _names_a_file(message: str, source: str) -> bool:
    """``message`` names ``source``, or starts with another file's name (``FILE: ...``,
    as a message about a size field or a frame does)."""
    import os

    head, sep, _ = message.partition(": ")
    return source in message or (bool(sep) and os.path.exists(head))


def names_its_file(fn):
    """Decorator: :func:`naming` the ``source`` of the function's first argument (a
    contour, or what holds one as ``contour``: a :class:`~.pipeline.Laid`); running
    out of memory becomes a :class:`LimitError` naming it too."""
    import functools

    @functools.wraps(fn)
    def wrapper(first, *args, **kwargs):
        with naming(source_of(first)):
            try:
                return fn(first, *args, **kwargs)
            except MemoryError:  # (one line naming the file, as any other failure)
                raise LimitError(OUT_OF_MEMORY) from None

    return wrapper


def source_of(obj) -> str | None:
    """The file ``obj`` came from: its ``source``, or its ``contour``'s."""
    while obj is not None and not isinstance(getattr(obj, "source", None), str):
        obj = getattr(obj, "contour", None)
    return None if obj is None else obj.source
