"""Triangle quality with and without the quality stage, next to Triangle's.

Usage: python benchmarks/run_quality.py [--repeat N]

For each contour: ``deformesh all`` with the stage (the default) and with
``--no-improve``, and Triangle (``pq30a<h^2/2>Y``, h = deformesh's h, so the
boundary nodes are the same points), each a whole process writing .vtk,
alternating, median of N.  Min angle and mean radius ratio are measured on the
written files by one code for all tools (``run_peers.py --quality``); the time
cost of the stage is the difference of the two deformesh medians.
"""

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from meshfiles import answered, asked
from results import heading, write_section
from run_contours import EXE, REFERENCE, ROOT, run_process
from run_peers import PEERS, PY, helper

CONTOURS = [REFERENCE / f"{s}_{n}.csv" for s in ("circle", "bean", "star") for n in (100, 1000)]
CONTOURS += [
    REFERENCE / f
    for f in ("channel_100.csv", "square_hole_100.csv", "naca0012_100.csv", "naca0012_1000.csv")
]
CONTOURS += [
    ROOT / "samples" / f
    for f in ("circle.csv", "peanut.csv", "half_disk.csv", "naca0012.csv", "paper_example.csv")
]
CORPUS = ROOT / "tests" / "data" / "corpus"
CONTOURS += [
    CORPUS / f
    for f in (
        "airfoil_clarky.csv",
        "airfoil_e387.csv",
        "airfoil_n0012.csv",
        "airfoil_sd7037.csv",
        "airfoil_usa35b.csv",
        "coast_cuba.csv",
        "icon_bi_bell-fill.svg",
    )
]


def points(src: str, out: str) -> dict:
    """Write the points deformesh reads from ``src`` as a plain x,y CSV."""
    import numpy as np

    from deformesh_cli.readers import load_contour

    c = load_contour(src)
    np.savetxt(out, c.points, delimiter=",", header="x,y", comments="", fmt="%.17g")
    return {"one_ring": c.n_rings == 1}


def main():
    if answered("--points", points):
        return
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for path in CONTOURS:
            out = {k: f"{d}/{k}.vtk" for k in ("on", "off", "triangle")}
            times = {k: [] for k in out}
            report = {}
            # Triangle gets the points deformesh read (one ring only: the peer has no holes)
            clean = f"{d}/points.csv"
            if not asked(__file__, "--points", path, clean)["one_ring"]:
                clean = None
            for _ in range(args.repeat):
                for k in ("on", "off"):
                    cmd = [EXE, "all", str(path), "-o", out[k], "--json", "-q"]
                    dt, _, code, text, err = run_process(
                        cmd + ([] if k == "on" else ["--no-improve"])
                    )
                    if code:
                        raise SystemExit(f"{path}: {err}")
                    times[k].append(dt)
                    report[k] = json.loads(text)
                if clean is not None:
                    h = report["on"]["h"]
                    dt, _, code, _, err = run_process(
                        [PY, str(PEERS / "triangle_mesh.py"), clean, repr(h), out["triangle"]]
                    )
                    if code:
                        raise SystemExit(f"triangle on {path}: {err}")
                    times["triangle"].append(dt)
            q = {k: helper("--quality", out[k]) for k in ("on", "off")}
            q["triangle"] = helper("--quality", out["triangle"]) if times["triangle"] else None
            med = {k: statistics.median(v) if v else float("nan") for k, v in times.items()}
            rows.append((path, report["on"], q, med))
            print(f"{path.name}: {q['off'][1]:.1f} -> {q['on'][1]:.1f} deg", file=sys.stderr)
    lines = heading(
        "## Quality stage, next to Triangle (whole processes writing .vtk, "
        f"median of {args.repeat}, alternating)",
        "deformesh with the stage (default) and with `--no-improve`; Triangle "
        "`pq30a<h^2/2>Y` with deformesh's h on the same points (CSV contours only). "
        "Quality measured on the written files by one code. Stage cost = seconds with "
        "minus seconds without (whole processes, so noisy at small sizes). Forced = the "
        "report's `forced_angle` where the mesh is under 30 degrees: no mesh with these "
        'boundary nodes has a larger smallest angle (README, "What the boundary forces").',
    ) + [
        "| contour | triangles | min angle without | min angle with | forced | "
        "Triangle min angle | mean radius ratio without | with | Triangle | "
        "seconds without | with | stage cost |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for path, rep, q, med in rows:
        tri = q["triangle"]
        t_ang = f"{tri[1]:.1f}" if tri else "-"
        t_rr = f"{tri[2]:.3f}" if tri else "-"
        f = rep.get("forced_angle")
        forced = "-" if f is None else f"{f:.1f}"
        lines.append(
            f"| {path.name} | {q['on'][0]} | {q['off'][1]:.1f} | {q['on'][1]:.1f} | {forced} | "
            f"{t_ang} | "
            f"{q['off'][2]:.3f} | {q['on'][2]:.3f} | {t_rr} | {med['off']:.2f} | "
            f"{med['on']:.2f} | {med['on'] - med['off']:+.2f} |"
        )
    write_section("quality", "\n".join(lines))


if __name__ == "__main__":
    main()
