"""Speed against peers: deformesh, Triangle and Gmsh side by side, as whole processes.

Usage: python benchmarks/run_peers.py [--repeat N] [--sizes 1e3,1e4,1e5,1e6]
                                       [--shapes circle,bean,naca0012] [--tools ...]
                                       [--section NAME]

For each shape and target triangle count, a contour of evenly spaced points is
made (spacing h chosen so that a grid of step h over the shape gives about that
many triangles) and meshed by each tool as its own process writing .vtk:

- deformesh: ``deformesh all IN.csv --h H -o OUT.vtk``;
- Triangle: ``pq30a<h^2/2>Y`` (benchmarks/peers/triangle_mesh.py);
- Gmsh: Frontal-Delaunay, size h at every contour point (benchmarks/peers/gmsh_mesh.py).

Runs alternate between the tools (tool A, B, C, A, B, C, ...) so that machine noise
hits them alike; the median of N runs is reported with the peak RSS (wait4), and
the quality of the mesh written (min angle, mean radius ratio), measured afterwards
by one code for all tools.  The peers come from the ``bench`` extra.

Peak RSS: Linux keeps a process's high-water mark across fork and exec, so a child
starts at its parent's RSS.  This process therefore imports nothing big: contours
are made and meshes measured in helper processes (``--make``, ``--quality``).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section
from run_contours import EXE, REFERENCE, run_process

PEERS = Path(__file__).resolve().parent / "peers"
PY = sys.executable


def _even(closed, n: int):
    """``n`` points evenly spaced by arc length along a closed polyline (dense input)."""
    import numpy as np

    p = np.vstack([closed, closed[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
    t = np.arange(n) * s[-1] / n
    return np.column_stack([np.interp(t, s, p[:, 0]), np.interp(t, s, p[:, 1])])


def shape(name: str):
    """A dense counter-clockwise outline of the shape (resampled later)."""
    import numpy as np

    t = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    if name == "circle":
        return np.column_stack([np.cos(t), np.sin(t)])
    if name == "bean":  # the shared bean, smoothed by a periodic cubic spline
        from scipy.interpolate import CubicSpline

        b = np.loadtxt(REFERENCE / "bean_100.csv", delimiter=",", skiprows=1)
        u = np.linspace(0, 1, len(b) + 1)
        cs = CubicSpline(u, np.vstack([b, b[:1]]), bc_type="periodic")
        return cs(np.linspace(0, 1, 20000, endpoint=False))
    if name == "naca0012":  # closed trailing edge (last coefficient -0.1036)
        x = (1 - np.cos(np.linspace(0, np.pi, 10000))) / 2
        yt = 0.6 * (
            0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3 - 0.1036 * x**4
        )
        upper = np.column_stack([x[::-1], yt[::-1]])
        lower = np.column_stack([x[1:-1], -yt[1:-1]])
        return np.vstack([upper, lower])
    raise ValueError(name)


def contour_for(name: str, triangles: float):
    """Points and spacing h so that a grid of step h over the shape has ~``triangles``."""
    import numpy as np

    dense = shape(name)
    x, y = dense.T
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    perim = np.hypot(*np.diff(np.vstack([dense, dense[:1]]), axis=0).T).sum()
    n = max(12, int(round(perim * np.sqrt(triangles / (2 * area)))))
    return _even(dense, n), float(perim / n)


def commands(tool: str, src: str, h: float, out: str) -> list[str]:
    if tool == "deformesh":
        return [EXE, "all", src, "--h", repr(h), "-o", out, "-q"]
    return [PY, str(PEERS / f"{tool}_mesh.py"), src, repr(h), out]


def make(name: str, size: float, out: str) -> dict:
    import numpy as np

    pts, h = contour_for(name, size)
    np.savetxt(out, pts, delimiter=",", header="x,y", comments="")
    return {"points": len(pts), "h": h}


def quality(path: str) -> tuple[int, float, float]:
    import meshio

    from deformesh_cli.quality import report

    m = meshio.read(path)
    r = report(m.points[:, :2], m.cells_dict["triangle"])
    return r["triangles"], r["min_angle"], r["mean_radius_ratio"]


def helper(*args) -> dict:
    """Run ``make`` or ``quality`` in a child process (keeps this one small)."""
    out = subprocess.run([PY, __file__, *args], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def main():
    if len(sys.argv) > 1 and sys.argv[1] in ("--make", "--quality"):
        fn = make if sys.argv[1] == "--make" else quality
        args = [float(a) if i == 1 and fn is make else a for i, a in enumerate(sys.argv[2:])]
        print(json.dumps(fn(*args)))
        return
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--sizes", default="1e3,1e4,1e5,1e6")
    ap.add_argument("--shapes", default="circle,bean,naca0012")
    ap.add_argument("--tools", default="deformesh,triangle,gmsh")
    ap.add_argument("--section", default="peers")
    args = ap.parse_args()
    tools = args.tools.split(",")
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for name in args.shapes.split(","):
            for size in (float(s) for s in args.sizes.split(",")):
                src = os.path.join(d, f"{name}.csv")
                made = helper("--make", name, str(size), src)
                npts, h = made["points"], made["h"]
                res = {t: {"times": [], "rss": 0.0, "code": 0, "err": ""} for t in tools}
                for _ in range(args.repeat):
                    for tool in tools:  # alternate: A B C A B C ...
                        out = os.path.join(d, f"{tool}.vtk")
                        dt, rss, code, _, err = run_process(commands(tool, src, h, out))
                        r = res[tool]
                        r["times"].append(dt)
                        r["rss"] = max(r["rss"], rss)
                        r["code"], r["err"] = code, err
                        if code == 0:
                            r["quality"] = helper("--quality", out)
                base = statistics.median(res["triangle"]["times"]) if "triangle" in res else None
                for tool in tools:
                    r = res[tool]
                    t = statistics.median(r["times"])
                    rows.append((name, npts, h, tool, t, r, base))
                    print(f"{name} {size:.0e} {tool}: {t:.2f} s, exit {r['code']}", file=sys.stderr)
    lines = heading(
        f"## Speed against peers: {', '.join(tools)} (whole processes writing .vtk, "
        f"median of {args.repeat}, alternating)",
        "Each contour has evenly spaced points at spacing h; every tool gets that h "
        "(deformesh `--h h`, Triangle `pq30a<h^2/2>Y`, Gmsh size h at every point). "
        "Quality is measured on the written file, by one code for all tools. "
        "Ratio = seconds / Triangle's seconds in the same run.",
    ) + [
        "| shape | points | h | tool | triangles | seconds | triangles/s | peak RSS MB | "
        "min angle | mean radius ratio | time ratio to Triangle | RSS ratio to Triangle |",
        "| --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    tri_rss = {(n, p): r["rss"] for n, p, _, tool, _, r, _ in rows if tool == "triangle"}
    for name, n, h, tool, t, r, base in rows:
        if r["code"] != 0:
            why = r["err"].splitlines()[-1][-80:] if r["err"] else ""
            lines.append(
                f"| {name} | {n} | {h:.3g} | {tool} | failed: {why} | "
                f"{t:.2f} | | {r['rss']:.0f} | | | | |"
            )
            continue
        ntri, amin, rr = r["quality"]
        ratio = f"{t / base:.2f}" if base else ""
        rss_ratio = f"{r['rss'] / tri_rss[(name, n)]:.2f}" if (name, n) in tri_rss else ""
        lines.append(
            f"| {name} | {n} | {h:.3g} | {tool} | {ntri} | {t:.2f} | {ntri / t:,.0f} | "
            f"{r['rss']:.0f} | {amin:.1f} | {rr:.3f} | {ratio} | {rss_ratio} |"
        )
    write_section(args.section, "\n".join(lines))


if __name__ == "__main__":
    main()
