"""Click options built from :mod:`deformesh_cli.options`, and what the commands share.

A command declares its options by field name (``@fields(MeshOptions, "h",
"box")``) and gets them back as one options object (:func:`take`): the flag,
default, choices and help text all come from the options class.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Callable
from typing import Any

import click

from .. import files
from ..errors import OptionError, WriteError, one_line
from ..options import STAGES, MeshOptions, flag
from ..options import fields as option_fields


class NumbersType(click.ParamType):
    """Comma-separated finite numbers, one per name in ``names``, as a tuple of floats."""

    names: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return ",".join(self.names)

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        count = {2: "two", 4: "four"}[len(self.names)]
        try:
            v = tuple(float(s) for s in value.split(","))
        except ValueError:
            self.fail(f"{value!r} is not {count} numbers {self.name}", param, ctx)
        if len(v) != len(self.names):
            self.fail(f"{value!r} has {len(v)} numbers, expected {self.name}", param, ctx)
        problem = self.problem(v)
        if problem:
            self.fail(f"{value!r} is not {problem}", param, ctx)
        return v

    def problem(self, v: tuple[float, ...]) -> str | None:
        """What the numbers fail to be, or None."""
        return None if all(math.isfinite(x) for x in v) else "four finite numbers"


class BoxType(NumbersType):
    """XMIN,YMIN,XMAX,YMAX as a tuple of four floats."""

    names = ("XMIN", "YMIN", "XMAX", "YMAX")


class VectorType(NumbersType):
    """DX,DY as a tuple of two finite floats, not both zero."""

    names = ("DX", "DY")

    def problem(self, v: tuple[float, ...]) -> str | None:
        if all(math.isfinite(x) for x in v) and v != (0.0, 0.0):
            return None
        return "a translation (two finite numbers, not both 0)"


def positive(ctx, param, value):
    """click callback: a finite number > 0 (or none given)."""
    if value is not None and not (value > 0 and math.isfinite(value)):
        raise click.BadParameter("must be a finite number > 0")
    return value


def click_option(f: dataclasses.Field, help: str | None = None) -> Callable:
    """The click option of one options field (``help``: another text than the field's)."""
    meta = f.metadata
    kind = meta["kind"]
    kw: dict[str, Any] = {"default": f.default, "help": help or meta["help"]}
    if "metavar" in meta:
        kw["metavar"] = meta["metavar"]
    decls = [flag(f), f.name]
    if kind == "flag":
        kw["is_flag"] = True
    elif kind == "switch":
        decls[0] = f"{flag(f)}/--no-{flag(f)[2:]}"
        kw["show_default"] = True
    elif kind == "choice":
        kw["type"] = click.Choice(meta["choices"], case_sensitive=f.name != "fmt")
        kw["show_default"] = f.default is not None
    elif kind == "positive":
        kw.update(type=float, callback=positive, show_default=f.default is not None)
    elif kind == "float":
        kw["type"] = float
    elif kind == "count":
        kw.update(type=click.IntRange(min=meta["min"], max=meta.get("max")), show_default=True)
    elif kind == "box":
        kw["type"] = BoxType()
    elif kind == "vector":
        kw["type"] = VectorType()
    elif kind == "path":
        kw["type"] = click.Path(dir_okay=False)
    return click.option(*decls, **kw)


def fields(cls: type, *names: str, helps: dict[str, str] | None = None) -> Callable:
    """Decorator: the click options of these fields of ``cls``, in this order (``helps``:
    other help texts, by field name)."""
    by_name = option_fields(cls)
    helps = helps or {}

    def deco(fn):
        for name in reversed(names):
            fn = click_option(by_name[name], helps.get(name))(fn)
        return fn

    return deco


def stages(*names: str) -> Callable:
    """Decorator: the click options of every :class:`MeshOptions` field these stages read."""
    return fields(MeshOptions, *(f for s in names for f in STAGES[s]))


#: What the reading options do for a command that reads a contour only to compare a
#: mesh with it (``quality``, ``plot``): read it as the mesh was made from it.
AS_MADE = {
    "element_id": "SVG: read only the element with this id, as the mesh was made.",
    "stroke": "SVG: read the outline of the stroked shapes, as the mesh was made.",
    "resample": "Re-space the contour at SPACING, as the mesh was made, so that its "
    "points are the mesh's contour nodes.",
}


def contour_reading() -> Callable:
    """Decorator: the options that read a contour, for a command that compares a mesh
    with the contour it was made from."""
    return fields(MeshOptions, *STAGES["read"], helps=AS_MADE)


def take(cls: type, kwargs: dict) -> Any:
    """Pop the fields of ``cls`` out of a command's keyword arguments; the options object."""
    return cls(**{name: kwargs.pop(name) for name in option_fields(cls) if name in kwargs})


class OutputPath(click.Path):
    """A file to write: ``-`` (if allowed), a new file, a regular file, or a symbolic link
    to one; a device, FIFO, socket or folder, or a folder that does not exist to write
    it in, is a usage error before any work is done."""

    def __init__(self, allow_dash: bool = True):
        super().__init__(dir_okay=False, allow_dash=allow_dash)

    def convert(self, value, param, ctx):
        value = super().convert(value, param, ctx)
        if value == "-" and self.allow_dash:
            return value
        try:
            files.output_target(value)
            files.check_folder(value)
        except OptionError as exc:
            hint = " (use '-' for stdout)" if self.allow_dash else ""
            self.fail(f"{exc}{hint}", param, ctx)
        except WriteError as exc:  # (a folder that does not exist: a usage error too)
            self.fail(str(exc), param, ctx)
        return value


def output_option(help: str, required: bool = True) -> Callable:
    return click.option(
        "-o",
        "--output",
        required=required,
        default=None,
        type=OutputPath(),
        help=help,
    )


def json_option(help: str = "Print the summary as JSON on stdout.") -> Callable:
    return click.option("--json", "as_json", is_flag=True, help=help)


quiet_option = click.option("-q", "--quiet", is_flag=True, help="Print errors only.")
png_option = click.option(
    "--png",
    type=OutputPath(allow_dash=False),
    default=None,
    help="Also draw the mesh to this PNG file (needs matplotlib).",
)


force_option = click.option(
    "--force",
    is_flag=True,
    help="Replace a sidecar file (.xdmf's NAME.h5) that deformesh did not write.",
)


def say(quiet: bool, msg: str) -> None:
    """A message on stderr, unless ``--quiet``."""
    if not quiet:
        click.echo(f"deformesh: {one_line(msg)}", err=True)


def check_binary_stdout(out: str) -> None:
    if out == "-" and sys.stdout is not None and sys.stdout.isatty():
        raise click.UsageError("refusing to write binary data to a terminal; use -o FILE or a pipe")
