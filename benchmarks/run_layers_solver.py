"""A wall layer solved on meshes with and without boundary layers (scikit-fem, P1).

Usage: python benchmarks/run_layers_solver.py

The cylinder of samples/circle.csv (radius 1, 64 points) in the box -4,-4,8,4; the
problem ``-eps Laplace(u) + b . grad(u) = f`` with ``eps = 1e-4``, ``b = (1, 0)`` and
``f`` made so that ``u = exp(-(r - 1) / delta)`` is the solution (``r`` the distance
from the cylinder's centre, ``delta = 0.05``: a wall layer a twentieth of the radius
thick, some 40 times the sagitta of the 64-gon's edges, so that the polygon's chords
leave ``u`` nearly constant along the wall), ``u`` given on the whole boundary.
Meshes: ``deformesh all --exterior`` with ``--layers 15 --first-height 0.002``
(``--layer-cells tri``), and without layers at
a ``--max-h`` chosen (by bisection, before any solve) so that it has about as many
nodes.  P1 with streamline-upwind Petrov-Galerkin stabilisation (plain Galerkin
oscillates at cell Peclet numbers in the hundreds on both meshes).  Errors against
the exact solution, in L2 and in the H1 seminorm.
"""

import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section
from run_contours import EXE

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "samples" / "circle.csv"
BOX = "-4,-4,8,4"
EPS, DELTA = 1e-4, 0.05
LAYERS = ["--layers", "15", "--first-height", "0.002", "--layer-cells", "tri"]


def mesh(out: str, *opts: str) -> None:
    cmd = [EXE, "all", str(SAMPLE), "--exterior", f"--box={BOX}", "-o", out, "-q", *opts]
    subprocess.run(cmd, check=True)


def exact(x, y):
    r = np.sqrt(x * x + y * y)
    u = np.exp(-(r - 1.0) / DELTA)
    du = -u / DELTA  # d/dr
    return u, du * x / r, du * y / r, r, du


def solve(path: str) -> dict:
    import skfem
    from skfem.helpers import dot, grad

    m = skfem.MeshTri.load(path)
    basis = skfem.Basis(m, skfem.ElementTriP1(), intorder=6)

    # Galerkin with streamline-upwind Petrov-Galerkin stabilisation (SUPG; the Laplacian
    # of a P1 function vanishes in a cell): tau = h / (2 |b|) (coth Pe - 1 / Pe), Pe =
    # |b| h / (2 eps), h the cell's length along b, 2 |b| / sum_i |b . grad phi_i| (a
    # layer cell is long across the flow at the front and along it at the sides)
    t = m.t
    py = m.p[1][t]
    area = 0.5 * np.abs(
        (m.p[0][t[1]] - m.p[0][t[0]]) * (py[2] - py[0])
        - (m.p[0][t[2]] - m.p[0][t[0]]) * (py[1] - py[0])
    )
    spread = np.abs(py[1] - py[2]) + np.abs(py[2] - py[0]) + np.abs(py[0] - py[1])
    along = 4.0 * area / spread  # (b = (1, 0): d phi_i / dx = (y_j - y_k) / (2 A))
    hb = skfem.DiscreteField(np.repeat(along[:, None], basis.X.shape[1], axis=1))

    def tau(w):
        pe = w["hb"] / (2.0 * EPS)
        return w["hb"] / 2.0 * (1.0 / np.tanh(pe) - 1.0 / pe)

    @skfem.BilinearForm
    def a(u, v, w):
        return EPS * dot(grad(u), grad(v)) + grad(u)[0] * v + tau(w) * grad(u)[0] * grad(v)[0]

    @skfem.LinearForm
    def rhs(v, w):
        x, y = w.x
        u, ux, uy, r, du = exact(x, y)
        d2u = u / DELTA**2  # d2/dr2
        f = -EPS * (d2u + du / r) + ux
        return f * v + tau(w) * f * grad(v)[0]

    A, b = a.assemble(basis, hb=hb), rhs.assemble(basis, hb=hb)
    x, y = m.p
    u_b = exact(x, y)[0]
    D = m.boundary_nodes()
    uh = skfem.solve(*skfem.condense(A, b, x=u_b, D=D))

    @skfem.Functional
    def l2(w):
        u, _, _, _, _ = exact(*w.x)
        return (w["uh"] - u) ** 2

    @skfem.Functional
    def h1(w):
        _, ux, uy, _, _ = exact(*w.x)
        g = w["uh"].grad
        return (g[0] - ux) ** 2 + (g[1] - uy) ** 2

    uh_i = basis.interpolate(uh)
    return {
        "nodes": int(m.nvertices),
        "triangles": int(m.nelements),
        "l2": float(np.sqrt(l2.assemble(basis, uh=uh_i))),
        "h1": float(np.sqrt(h1.assemble(basis, uh=uh_i))),
    }


def nodes(path: str) -> int:
    import meshio

    return len(meshio.read(path).points)


def main():
    with tempfile.TemporaryDirectory() as d:
        with_layers = str(Path(d) / "layers.msh")
        mesh(with_layers, *LAYERS)
        target = nodes(with_layers)
        lo, hi = 0.005, 2.0  # --max-h: many nodes .. few
        plain = str(Path(d) / "plain.msh")
        for _ in range(30):
            mid = (lo * hi) ** 0.5
            mesh(plain, "--max-h", f"{mid:.6g}")
            if nodes(plain) > target:
                lo = mid
            else:
                hi = mid
        mesh(plain, "--max-h", f"{hi:.6g}")
        rows = [("with layers", " ".join(LAYERS), solve(with_layers))]
        rows.append(("without layers", f"--max-h {hi:.4g}", solve(plain)))
    lines = heading(
        "## A wall layer solved with and without boundary layers (scikit-fem, P1)",
        "`python benchmarks/run_layers_solver.py`: samples/circle.csv (radius 1) in the box "
        f"{BOX}, `-eps Laplace(u) + b . grad(u) = f`, eps = {EPS:g}, b = (1, 0), f made so "
        f"that u = exp(-(r - 1) / {DELTA:g}) (a wall layer a twentieth of the radius "
        "thick), u given on the boundary; P1 with SUPG; errors against u. The mesh "
        "without layers is refined by `--max-h` to about the same node count.",
    ) + [
        "| mesh | options | nodes | triangles | L2 error | H1 seminorm error |",
        "| --- | --- | ---: | ---: | ---: | ---: |",
    ]
    for name, opts, r in rows:
        lines.append(
            f"| {name} | `{opts}` | {r['nodes']} | {r['triangles']} | {r['l2']:.3g} | "
            f"{r['h1']:.3g} |"
        )
        print(lines[-1], file=sys.stderr)
    write_section("layers-solver", "\n".join(lines))


if __name__ == "__main__":
    main()
