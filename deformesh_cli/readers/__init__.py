"""Contour readers: a file's bytes -> a validated :class:`~deformesh_cli.contour.Contour`.

One module per input format (:mod:`.csv`, :mod:`.svg`, :mod:`.geojson`);
:func:`load_contour` picks one by the file's extension or its first bytes, and
names the format of a file it cannot read (DXF, shapefiles, meshes, ...).
"""

from __future__ import annotations

from pathlib import Path

from ..contour import Contour, parse_spacing, resample
from ..errors import InputError, OptionError
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
    stroke: bool = False,
) -> Contour:
    """Read a contour file: CSV, SVG (by extension, or text starting with ``<``) or
    GeoJSON (by extension, or text starting with ``{``).

    ``data``, if given, are the file's bytes (``path`` names them; ``-`` is
    stdin).  ``decimal`` is the CSV decimal mark (``.`` or ``,``);
    ``tolerance``, ``element_id`` and ``stroke`` are the SVG options (see
    :func:`.svg.parse_svg`); ``resample_spacing`` (the text of
    ``--resample``) re-spaces the contour read (:func:`resample`).
    """
    c = _read(path, data, decimal, tolerance, element_id, stroke)
    if resample_spacing is not None:
        c = resample(c, parse_spacing(resample_spacing, c))
    return c


def _read(path, data, decimal, tolerance, element_id, stroke=False) -> Contour:
    name = "<stdin>" if str(path) == "-" else str(path)
    if data is None:
        data = read_bytes(str(path))
    suffix = Path(name).suffix.lower()
    if suffix in OTHER_FORMATS:  # (a .vtu starts with "<" too)
        raise InputError(_not_a_contour(name, OTHER_FORMATS[suffix]))
    if suffix in (".svg", ".svgz") or data.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"<"):
        from .svg import read_svg  # svgelements loads only for SVG input

        return read_svg(data, name, tolerance, element_id, suffix == ".svgz", stroke)
    if tolerance is not None or element_id is not None or stroke:
        raise OptionError(f"{name}: --tolerance, --id and --stroke apply to SVG input only")
    if suffix in (".geojson", ".json") or data.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"{"):
        from .geojson import read_geojson

        return read_geojson(data, name)
    other = _other_format(data)
    if other is not None:
        raise InputError(_not_a_contour(name, other))
    return read_csv(data, name, decimal)


def _not_a_contour(name: str, what: str) -> str:
    return (
        f"{name}: {what} is not a contour format deformesh reads; "
        "give CSV (x,y columns), SVG or GeoJSON"
    )


#: Formats people have that are not contours deformesh reads, by extension.
OTHER_FORMATS = {
    ".dxf": "DXF",
    ".dwg": "DWG",
    ".shp": "an ESRI shapefile",
    ".kml": "KML",
    ".kmz": "KMZ",
    ".gpkg": "a GeoPackage",
    ".stl": "STL",
    ".step": "STEP",
    ".stp": "STEP",
    ".iges": "IGES",
    ".igs": "IGES",
    ".pdf": "PDF",
    ".eps": "EPS",
    ".png": "a PNG image",
    ".jpg": "a JPEG image",
    ".jpeg": "a JPEG image",
    ".msh": "a Gmsh mesh",
    ".vtk": "a VTK mesh",
    ".vtu": "a VTK mesh",
    ".xdmf": "an XDMF mesh",
    ".html": "an HTML page",
    ".htm": "an HTML page",
    ".xlsx": "an Excel workbook",
}


def _other_format(data: bytes) -> str | None:
    """The name of a known format that is not a contour, by its first bytes."""
    head = data[:64].lstrip()
    if head.startswith(b"0") and b"SECTION" in data[:256]:
        return "DXF"
    if head.startswith(b"%PDF"):
        return "PDF"
    if head.startswith(b"\x89PNG"):
        return "a PNG image"
    if head.startswith(b"$MeshFormat"):
        return "a Gmsh mesh"
    if head.startswith(b"# vtk DataFile"):
        return "a VTK mesh"
    return None
