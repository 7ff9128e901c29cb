"""Contour readers: a file's bytes -> a validated :class:`~deformesh_cli.contour.Contour`.

One module per input format (:mod:`.csv`, :mod:`.svg`); :func:`load_contour`
picks one by the file's extension or its first bytes.
"""

from __future__ import annotations

from pathlib import Path

from ..contour import Contour, parse_spacing, resample
from ..errors import OptionError
from ..files import read_bytes
from .csv import parse_csv, read_csv

__all__ = ["load_contour", "parse_csv"]


def load_contour(
    path: str | Path,
    data: bytes | None = None,
    decimal: str = ".",
    tolerance: str | float | None = None,
    element_id: str | None = None,
    resample_spacing: str | float | None = None,
) -> Contour:
    """Read a contour file: CSV, or SVG (by extension, or text starting with ``<``).

    ``data``, if given, are the file's bytes (``path`` names them; ``-`` is
    stdin).  ``decimal`` is the CSV decimal mark (``.`` or ``,``);
    ``tolerance`` and ``element_id`` are the SVG options (see
    :func:`.svg.parse_svg`); ``resample_spacing`` (the text of
    ``--resample``) re-spaces the contour read (:func:`resample`).
    """
    c = _read(path, data, decimal, tolerance, element_id)
    if resample_spacing is not None:
        c = resample(c, parse_spacing(resample_spacing, c))
    return c


def _read(path, data, decimal, tolerance, element_id) -> Contour:
    name = "<stdin>" if str(path) == "-" else str(path)
    if data is None:
        data = read_bytes(str(path))
    suffix = Path(name).suffix.lower()
    if suffix in (".svg", ".svgz") or data.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"<"):
        from .svg import read_svg  # svgelements loads only for SVG input

        return read_svg(data, name, tolerance, element_id, gzipped=suffix == ".svgz")
    if tolerance is not None or element_id is not None:
        raise OptionError(f"{name}: --tolerance and --id apply to SVG input only")
    return read_csv(data, name, decimal)
