"""What a mesh format is to deformesh: a writer and what the files can carry."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from ..mesh import Mesh

#: ``write(mesh, path, version)``: write ``mesh`` to the file ``path`` (``version``: one of
#: the format's :attr:`Format.versions`, or None for its default).
Writer = Callable[[Mesh, str, "str | None"], None]


@dataclass(frozen=True, kw_only=True)
class Format:
    """One output format.

    Attributes
    ----------
    name : the file extension, lower case (``vtk``).
    description : one line for ``--help`` and the docs.
    write : the :data:`Writer` of a one-file format, or None.
    boundary_groups : the boundary's named groups (``contour``, ``hole_1``, the box
        sides) survive in the file.
    point_data : per-node arrays (``contour_point``, a moving mesh's ``velocity``) are
        written.
    sidecar : extension of a second file written beside the first (``.h5``), or None.
    render : for a format with a sidecar (instead of ``write``), ``render(mesh, file
        name) -> (file bytes, sidecar bytes)``, both made in memory.
    sidecar_mark : the first bytes of every sidecar deformesh writes: an existing
        sidecar without them is a user's file (replaced only with ``--force``).
    meshio_format : the name meshio reads the file back by, or None if it cannot.
    versions : the file versions ``--msh-version`` offers, the default first.
    binary : the file is binary (not text): never written to a terminal.
    """

    name: str
    description: str
    write: Writer | None = None
    boundary_groups: bool = False
    point_data: bool = False
    sidecar: str | None = None
    render: Callable[[Mesh, str], tuple[bytes, bytes]] | None = None
    sidecar_mark: bytes = b""
    meshio_format: str | None = None
    versions: tuple[str, ...] = field(default=())
    binary: bool = False

    @property
    def stdout(self) -> bool:
        """The mesh fits on stdout (one file, no sidecar)."""
        return self.sidecar is None

    @property
    def readable(self) -> bool:
        """``deformesh quality``, ``plot`` and ``move`` can read it back."""
        return self.meshio_format is not None
