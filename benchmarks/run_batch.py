"""Time batch meshing: one process per contour (a shell loop) vs one `deformesh all
FOLDER --out-dir` with --jobs 1 and 2; write benchmarks/BATCH.md.

Usage: python benchmarks/run_batch.py [--repeat N] [--copies K]   (make bench)
The three ways run interleaved, N rounds, so machine noise hits them alike;
compare the ratios.
"""

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading
from run_contours import EXE, REFERENCE, ROOT

CONTOURS = [
    REFERENCE / n
    for n in (
        "circle_100.csv",
        "bean_100.csv",
        "star_100.csv",
        "channel_100.csv",
        "square_hole_100.csv",
    )
] + [ROOT / "samples" / n for n in ("circle.csv", "peanut.csv", "paper_example.csv", "bracket.svg")]


def timed(cmd):
    t = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--copies", type=int, default=3, help="copies of each contour")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        src = Path(d) / "in"
        src.mkdir()
        for k in range(args.copies):
            for c in CONTOURS:
                (src / f"{c.stem}_{k}{c.suffix}").write_bytes(c.read_bytes())
        files = sorted(src.iterdir())
        ways = {
            "one process per contour": lambda: sum(
                timed([EXE, "all", str(f), "-o", f"{d}/loop.msh", "-q"]) for f in files
            ),
            "batch --jobs 1": lambda: timed(
                [EXE, "all", str(src), "--out-dir", f"{d}/o1", "--jobs", "1", "-q"]
            ),
            "batch --jobs 2": lambda: timed(
                [EXE, "all", str(src), "--out-dir", f"{d}/o2", "--jobs", "2", "-q"]
            ),
        }
        times = {k: [] for k in ways}
        for _ in range(args.repeat):
            for k, fn in ways.items():
                times[k].append(fn())
                print(f"{k}: {times[k][-1]:.2f} s", file=sys.stderr)
    base = statistics.median(times["one process per contour"])
    lines = heading(
        "# Batch benchmark",
        f"{len(files)} contours ({args.copies} copies each of "
        f"{', '.join(c.name for c in CONTOURS)}), meshed to .msh. Median of {args.repeat} "
        "interleaved rounds (written by `make bench`).",
    ) + [
        "| way | seconds | vs one process per contour |",
        "| --- | ---: | ---: |",
    ]
    for k in ways:
        t = statistics.median(times[k])
        lines.append(f"| {k} | {t:.2f} | {t / base:.2f} |")
    out = ROOT / "benchmarks" / "BATCH.md"
    out.write_text("\n".join(lines) + "\n")
    print(f"wrote {out}", file=sys.stderr)


if __name__ == "__main__":
    main()
