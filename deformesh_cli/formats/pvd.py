"""ParaView collections (``.pvd``): a time series of mesh files."""

from __future__ import annotations


def pvd_bytes(entries: list[tuple[float, str]]) -> bytes:
    """A ``.pvd`` file listing ``(time, file name)``, the names relative to its folder."""
    from xml.sax.saxutils import quoteattr  # (it loads urllib and email: only here)

    rows = "".join(
        f'    <DataSet timestep="{float(t)!r}" group="" part="0" file={quoteattr(name)}/>\n'
        for t, name in entries
    )
    return (
        '<?xml version="1.0"?>\n'
        '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
        f"  <Collection>\n{rows}  </Collection>\n</VTKFile>\n"
    ).encode()
