"""Start-up: what a run on a tiny contour costs before any work, next to Triangle.

Times whole processes on a 4-point square (``deformesh all square.csv -o m.vtk``
against Triangle ``pq30Y`` in python writing .vtk with meshio, in turn, median of
``--repeat``), and lists what the deformesh run imports (``python -X importtime``:
each top-level module's cumulative import time, and the largest).  Writes the section
"startup" of benchmarks/RESULTS.md.

Usage: python benchmarks/run_startup.py [--repeat 9]
"""

import argparse
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section
from run_circles import TRIANGLE, timed
from run_contours import EXE


def imports(cmd: list[str]) -> tuple[list[tuple[int, str]], set[str]]:
    """``(microseconds, module)`` of each module imported at top level (not by another
    module), largest first; and every module imported."""
    err = subprocess.run(cmd, capture_output=True, text=True, check=True).stderr
    out, every = [], set()
    for line in err.splitlines():
        if not line.startswith("import time:") or "|" not in line:
            continue
        _, cumulative, name = line.split("|")
        every.add(name.strip())
        if name.startswith(" ") and not name.startswith("  ") and cumulative.strip().isdigit():
            out.append((int(cumulative), name.strip()))
    return sorted(out, reverse=True), every


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=9)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src = tmp / "square.csv"
        src.write_text("0,0\n1,0\n1,1\n0,1\n")
        ours, theirs = [], []
        for _ in range(args.repeat):
            ours.append(timed([EXE, "all", str(src), "-o", str(tmp / "d.vtk"), "-q"]))
            theirs.append(timed([sys.executable, "-c", TRIANGLE, str(src), str(tmp / "t.vtk")]))
        cmd = [sys.executable, "-X", "importtime", "-m", "deformesh_cli", "all", str(src)]
        top, names = imports([*cmd, "-o", str(tmp / "i.vtk"), "-q"])
    d, t = statistics.median(s for s, _ in ours), statistics.median(s for s, _ in theirs)
    lines = heading(
        "## Start-up: a 4-point square (whole processes writing .vtk)",
        f"Median of {args.repeat} runs, deformesh and Triangle `pq30Y` in turn; peak "
        "resident memory in MB; then what `python -X importtime -m deformesh_cli all "
        "square.csv -o m.vtk` imports at top level (cumulative milliseconds).",
    )
    lines += [
        "| tool | s | MB |",
        "| --- | ---: | ---: |",
        f"| deformesh | {d:.3f} | {max(m for _, m in ours):.0f} |",
        f"| Triangle (python, triangle, meshio) | {t:.3f} | {max(m for _, m in theirs):.0f} |",
        "",
        "| module | ms |",
        "| --- | ---: |",
    ]
    lines += [f"| `{name}` | {us / 1000:.1f} |" for us, name in top[:12]]
    absent = ("scipy.spatial", "matplotlib", "h5py", "pyamg", "svgelements")
    lines += ["", "Not imported: " + ", ".join(f"`{m}`" for m in absent if m not in names) + "."]
    write_section("startup", "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
