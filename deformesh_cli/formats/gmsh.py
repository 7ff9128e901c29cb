"""Gmsh ASCII, version 2.2 (default) or 4.1: triangles (and quads) in the physical group ``domain``,
one block of lines per boundary group, the names in ``$PhysicalNames``.

Version 2.2 by :func:`write_22`, byte for byte what meshio writes for the
same blocks (:func:`write_meshio`, tested), only faster; 4.1 by meshio.
Never ANSYS: meshio writes that for ``.msh`` unless told otherwise.
"""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh
from ..periodic import side_roles
from ._common import cell_blocks, groups, rows
from .format import Format

#: Gmsh file versions (``--msh-version``, the default first) -> meshio format name.
MESHIO_NAMES = {"2.2": "gmsh22", "4.1": "gmsh"}

_GMSH_TYPE = {"triangle": 2, "quad": 3, "line": 1}

#: The surface entity of each kind of 2D cell.
SURFACE = {"triangle": 1, "quad": 2}


def blocks(mesh: Mesh) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """Element blocks as ``(meshio type, physical tags, geometrical tags, connectivity)``:
    the triangles and any quads (physical ``domain``; geometrical 1 for the triangles,
    2 for the quads: meshio writes one kind of element per entity), then one block of
    lines per boundary curve (:func:`line_curves`; physical: the group's tag)."""
    line_tag = (mesh.line_group + 1).astype(np.int64)
    curve = line_curves(mesh)
    domain = groups(mesh)["domain"][0]
    out = [
        (kind, np.full(len(cells), domain), np.full(len(cells), SURFACE[kind]), cells)
        for kind, cells in cell_blocks(mesh)[:-1]
    ]
    for tag in np.unique(curve):
        on = curve == tag
        out.append(("line", line_tag[on], curve[on], mesh.lines[on].astype(np.int64)))
    return out


def line_curves(mesh: Mesh) -> np.ndarray:
    """Each boundary line's curve (Gmsh's geometrical entity): its group's tag, but on a
    periodic mesh the lines of the sides that repeat get curves of their own (tags
    after the groups', one per group and role: Gmsh links one curve to another, never
    a curve to itself, and one ring can hold both sides of a channel)."""
    curve = (mesh.line_group + 1).astype(np.int64)
    role = side_roles(mesh)
    if role is None:
        return curve
    sides = sorted(set(zip(role[role > 0].tolist(), curve[role > 0].tolist())))
    new = {key: len(mesh.groups) + 2 + k for k, key in enumerate(sides)}  # (after domain)
    for k in np.flatnonzero(role > 0).tolist():
        curve[k] = new[int(role[k]), int(curve[k])]
    return curve


def periodic_links(mesh: Mesh) -> list:
    """The mesh's periodic pairs as Gmsh links, in meshio's ``gmsh_periodic`` form:
    per pair of curves ``[1, (curve, master curve), affine, (k, 2) nodes]``, each
    node (the *slave*, Gmsh's word) the partner at ``master + shift``; a pair's
    curves are those of the side lines its nodes end (:func:`line_curves`), the
    affine map the shift's."""
    if not len(mesh.periodic):
        return []
    curve, role = line_curves(mesh), side_roles(mesh)
    master_on = np.zeros(mesh.n_nodes, dtype=np.int64)
    slave_on = np.zeros(mesh.n_nodes, dtype=np.int64)
    for k in (0, 1):
        master_on[mesh.lines[role == 1, k]] = curve[role == 1]
        slave_on[mesh.lines[role == 2, k]] = curve[role == 2]
    master, slave = mesh.periodic[:, 0], mesh.periodic[:, 1]
    dx, dy = mesh.shift
    affine = [1.0, 0.0, 0.0, dx, 0.0, 1.0, 0.0, dy, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    links = []
    for s_tag, m_tag in sorted(set(zip(slave_on[slave].tolist(), master_on[master].tolist()))):
        at = (slave_on[slave] == s_tag) & (master_on[master] == m_tag)
        links.append([1, (s_tag, m_tag), affine, np.column_stack([slave[at], master[at]])])
    return links


def write(mesh: Mesh, path: str, version: str | None = None) -> None:
    """Gmsh ASCII in ``version`` (default 2.2)."""
    if version in (None, "2.2"):
        return write_22(mesh, path)
    write_meshio(mesh, path, version)


def write_meshio(mesh: Mesh, path: str, version: str) -> None:
    """The same file by meshio's writer."""
    import meshio

    bl = blocks(mesh)
    point_data = {}
    if version == "4.1":
        # 4.1 files place every node on a geometric entity: boundary nodes on
        # their boundary's curve (tag = group tag), the quads' other nodes on surface 2,
        # the rest on surface 1
        line_tag = line_curves(mesh)
        dim_tags = np.column_stack([np.full(mesh.n_nodes, 2), np.ones(mesh.n_nodes)])
        dim_tags[mesh.quads.ravel(), 1] = 2  # (the quads' surface)
        dim_tags[mesh.lines[:, 0]] = np.column_stack([np.ones(len(line_tag)), line_tag])
        point_data = {"gmsh:dim_tags": dim_tags.astype(np.int32)}
    m = meshio.Mesh(
        mesh.points,
        [(kind, conn) for kind, _, _, conn in bl],
        point_data=point_data,
        cell_data={
            "gmsh:physical": [b[1].astype(np.int32) for b in bl],
            "gmsh:geometrical": [b[2].astype(np.int32) for b in bl],
        },
    )
    m.field_data = {name: np.array([tag, dim]) for name, (tag, dim) in groups(mesh).items()}
    links = periodic_links(mesh)
    if links:
        m.gmsh_periodic = links
    meshio.write(path, m, file_format=MESHIO_NAMES[version], binary=False)
    if version == "4.1":  # (both sections rewritten in one pass over the file)
        _replace_sections(
            path,
            {
                "Entities": _all_entities(mesh, bl),
                "Nodes": _nodes_in_order(mesh.points, point_data["gmsh:dim_tags"]),
            },
        )


def _all_entities(mesh: Mesh, bl) -> str:
    """The ``$Entities`` section of a 4.1 file listing every entity an element block
    names: meshio lists only those that hold a node, and a surface whose nodes all lie
    on the boundary or on the other surface would be missing (Gmsh then refuses the
    file).  The same lines as meshio's: no bounding box, one physical tag, no bounding
    entities."""
    curves = sorted({(int(b[2][0]), int(b[1][0])) for b in bl if b[0] == "line"})
    surfaces = sorted({int(b[2][0]) for b in bl if b[0] != "line"})
    domain = groups(mesh)["domain"][0]
    out = [f"$Entities\n0 {len(curves)} {len(surfaces)} 0\n"]
    out += [f"{t} 0 0 0 0 0 0 1 {phys} 0\n" for t, phys in curves]
    out += [f"{t} 0 0 0 0 0 0 1 {domain} 0\n" for t in surfaces]
    out.append("$EndEntities\n")
    return "".join(out)


def _nodes_in_order(points: np.ndarray, dim_tags: np.ndarray) -> str:
    """The ``$Nodes`` section of a 4.1 file with its node blocks in node order: one
    block per run of consecutive nodes on the same entity.  meshio
    writes one block per entity, sorted by entity, and readers that take the nodes in
    file order (meshio's, scikit-fem's) then number them differently from the tags:
    node ``k`` would no longer be contour point ``k``."""
    n = len(points)
    change = np.flatnonzero((dim_tags[1:] != dim_tags[:-1]).any(axis=1)) + 1
    starts, ends = np.r_[0, change], np.r_[change, n]
    xyz = np.column_stack([points, np.zeros(n)])
    out = [f"$Nodes\n{len(starts)} {n} 1 {n}\n"]
    for a, b in zip(starts.tolist(), ends.tolist()):
        dim, tag = dim_tags[a].tolist()
        out.append(f"{dim} {tag} 0 {b - a}\n")
        out.append(rows("%d\n", np.arange(a + 1, b + 1)[:, None]))
        out.append(rows("%.16e %.16e %.16e\n", xyz[a:b]))
    out.append("$EndNodes\n")
    return "".join(out)


def _replace_sections(path: str, sections: dict[str, str]) -> None:
    """Put each of ``sections`` (``NAME``: the text from ``$NAME`` to ``$EndNAME``, both
    lines included) in place of the file's own, in one read and one write."""
    with open(path, encoding="ascii") as f:
        text = f.read()
    for name, section in sections.items():
        head, rest = text.split(f"${name}\n", 1)
        text = head + section + rest.split(f"$End{name}\n", 1)[1]
    with open(path, "w", encoding="ascii") as f:
        f.write(text)


def write_22(mesh: Mesh, path: str) -> None:
    """Gmsh 2.2 ASCII, one %-format per table."""
    names = sorted((dim, tag, name) for name, (tag, dim) in groups(mesh).items())
    bl = blocks(mesh)
    n = mesh.n_nodes
    parts = ["$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"]
    if names:
        parts.append(f"$PhysicalNames\n{len(names)}\n")
        parts += [f'{dim} {tag} "{name}"\n' for dim, tag, name in names]
        parts.append("$EndPhysicalNames\n")
    nodes = np.empty((n, 4), dtype=object)
    nodes[:, 0] = np.arange(1, n + 1)
    nodes[:, 1:3] = mesh.points
    nodes[:, 3] = 0.0
    parts += [f"$Nodes\n{n}\n", rows("%d %.16e %.16e %.16e\n", nodes), "$EndNodes\n"]
    parts.append(f"$Elements\n{sum(len(b[3]) for b in bl)}\n")
    first = 1
    for kind, phys, geom, conn in bl:
        k = len(conn)
        table = np.column_stack([np.arange(first, first + k), phys, geom, conn + 1])
        parts.append(rows(f"%d {_GMSH_TYPE[kind]} 2" + " %d" * (2 + conn.shape[1]) + "\n", table))
        first += k
    parts.append("$EndElements\n")
    links = periodic_links(mesh)
    if links:  # (as meshio writes it)
        parts.append(f"$Periodic\n{len(links)}\n")
        for dim, (s_tag, m_tag), affine, pairs in links:
            parts.append(f"{dim} {s_tag} {m_tag}\nAffine ")
            parts.append(" ".join(f"{v:.16e}" for v in affine) + "\n")
            parts.append(f"{len(pairs)}\n" + rows("%d %d\n", pairs + 1))
        parts.append("$EndPeriodic\n")
    with open(path, "w", encoding="ascii", newline="\n") as fh:
        fh.writelines(parts)


FORMAT = Format(
    name="msh",
    description="Gmsh 2.2 ASCII with named physical groups (4.1 with --msh-version)",
    write=write,
    boundary_groups=True,
    meshio_format="gmsh",
    versions=tuple(MESHIO_NAMES),
)
