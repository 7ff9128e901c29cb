"""Time `deformesh all` as a whole process on the issue-2 contours; write RESULTS.md.

Usage: python benchmarks/run_contours.py [--repeat N]   (make bench)
Whole processes, median of N runs, peak RSS from the child's rusage.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section

ROOT = Path(__file__).resolve().parent.parent
REFERENCE = ROOT / "tests" / "data" / "contours"
EXE = str(Path(sys.executable).parent / "deformesh")

CASES = [
    ("samples/circle.csv", []),
    ("samples/naca0012.csv", []),
    ("samples/peanut.csv", []),
    ("samples/half_disk.csv", ["--box=-1.25,0,1.25,1.25"]),
    ("samples/paper_example.csv", ["--h", "1", "--box", "1,1,9,12"]),
    ("circle_100.csv", []),
    ("circle_1000.csv", []),
    ("bean_100.csv", []),
    ("star_100.csv", []),
    ("channel_100.csv", []),
    ("naca0012_100.csv", ["--h", "0.01"]),
    ("naca0012_100.csv", []),
    ("naca0012_1000.csv", []),  # the adapted grid: exactly its 1,000 points
    ("naca0012_1000.csv", ["--grid", "uniform"]),  # refused: measures the time to refuse
    ("naca0012_1000.csv", ["--resample", "0.5%"]),  # what the refusal advises
    ("circle_1000.csv", ["--solve", "full"]),  # the whole-grid solve, next to the band
]


def run_process(cmd: list[str]) -> tuple[float, float, int, str, str]:
    """One whole process: (seconds, its own peak RSS in MB from wait4, exit code, stdout,
    stderr).  The caller should be a small process: Linux carries the parent's RSS into
    a forked child's high-water mark."""
    with tempfile.TemporaryFile("w+") as fo, tempfile.TemporaryFile("w+") as fe:
        t = time.perf_counter()
        p = subprocess.Popen(cmd, stdout=fo, stderr=fe)
        _, status, usage = os.wait4(p.pid, 0)
        dt = time.perf_counter() - t
        fo.seek(0)
        fe.seek(0)
        return (
            dt,
            usage.ru_maxrss / 1024,
            os.waitstatus_to_exitcode(status),
            fo.read(),
            fe.read().strip(),
        )


def run_once(path, opts, out):
    """``deformesh all`` on one contour: (seconds, peak RSS MB, exit code, record)."""
    dt, rss, code, out_text, err = run_process(
        [EXE, "all", str(path), "-o", out, "--json", "-q", *opts]
    )
    return dt, rss, code, (json.loads(out_text) if code == 0 else {"error": err})


def timed(path, opts, out, repeat: int) -> tuple[float, float, int, dict]:
    """:func:`run_once` ``repeat`` times: (median seconds, peak RSS MB, the last exit
    code and record)."""
    times, rss, code, rec = [], 0.0, 0, {}
    for _ in range(repeat):
        dt, mb, code, rec = run_once(path, opts, out)
        times.append(dt)
        rss = max(rss, mb)
    return statistics.median(times), rss, code, rec


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for name, opts in CASES:
            path = ROOT / name if name.startswith("samples/") else REFERENCE / name
            t, rss, code, rec = timed(path, opts, os.path.join(d, "m.vtk"), args.repeat)
            rows.append((name, " ".join(opts), t, rss, code, rec))
            print(f"{name}: {t:.2f} s exit {code}", file=sys.stderr)
    lines = heading(
        "## Contours: `deformesh all` per contour (whole process, median of "
        f"{args.repeat}, written by `make bench`)",
        "Peak RSS of each process from wait4. A refusal's time is the whole process "
        "(Python start-up and imports included).",
    ) + [
        "| contour | options | seconds | peak RSS MB | exit | grid nodes | moved nodes | "
        "triangles | min angle | extra boundary nodes |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for name, opts, t, rss, code, rec in rows:
        if code == 0:
            lines.append(
                f"| {name} | {opts} | {t:.2f} | {rss:.0f} | 0 | {rec['grid_nodes']} | "
                f"{rec['moved_nodes']} | {rec['triangles']} | {rec['min_angle']:.2f} | "
                f"{rec['extra_boundary_nodes']} |"
            )
        else:
            msg = rec["error"].split(": error: ", 1)[-1][:90]
            lines.append(
                f"| {name} | {opts} | {t:.2f} | {rss:.0f} | {code} | refused: {msg}... | | | | |"
            )
    write_section("contours", "\n".join(lines))


if __name__ == "__main__":
    main()
