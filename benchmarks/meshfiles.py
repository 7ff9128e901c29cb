"""What the side-by-side benchmarks share to read both tools' files the same way."""

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path


def answered(flag: str, fn) -> bool:
    """Whether this process was started as ``SCRIPT FLAG ARGS...``; if so, ``fn(*ARGS)``
    is printed as JSON (for :func:`asked`), and the caller returns."""
    if len(sys.argv) > 1 and sys.argv[1] == flag:
        print(json.dumps(fn(*sys.argv[2:])))
        return True
    return False


def asked(script, flag: str, *args) -> dict:
    """``script FLAG ARGS`` in a process of its own (:func:`answered`), its JSON answer:
    what the answer imports stays out of the benchmark's process, which stays small
    (a forked child's peak RSS counts its parent's)."""
    cmd = [sys.executable, str(script), flag, *map(str, args)]
    return json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout)


def read_cells(mesh_path: str, contour_path: str):
    """A mesh file read by meshio: ``(points (n, 2), triangles, quads, found)``,
    ``found[k]`` the node at contour point ``k``'s exact coordinates, or -1."""
    import meshio
    import numpy as np

    from deformesh_cli.readers import load_contour

    m = meshio.read(mesh_path)
    p = np.asarray(m.points[:, :2], dtype=np.float64)
    tri = np.concatenate([c.data for c in m.cells if c.type == "triangle"] or [np.zeros((0, 3))])
    quads = np.concatenate([c.data for c in m.cells if c.type == "quad"] or [np.zeros((0, 4))])
    c = load_contour(contour_path).points
    key = {(float(x), float(y)): k for k, (x, y) in enumerate(p.tolist())}
    found = [key.get((float(x), float(y)), -1) for x, y in c.tolist()]
    return p, tri.astype(np.int64), quads.astype(np.int64), found


def plain_csv(src) -> str:
    """The contour file ``src`` without its comment lines, in the temporary folder (the
    peers read ``x,y`` rows)."""
    path = os.path.join(tempfile.gettempdir(), "deformesh_" + Path(src).stem + "_plain.csv")
    rows = [ln for ln in Path(src).read_text().splitlines() if not ln.startswith("#")]
    Path(path).write_text("\n".join(rows) + "\n")
    return path
