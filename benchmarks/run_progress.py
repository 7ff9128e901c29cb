"""What saying how far a batch is costs: the same batch with and without progress.

Usage: python benchmarks/run_progress.py [--repeat N]

A batch of 50 contours (the samples' CSV files, copied in turn) meshed by
``deformesh all DIR --out-dir OUT -j 2`` three ways, in turn, the median of N runs
each, their order turned each round: ``--no-progress``; stderr piped (plain lines at
every tenth); stderr on a pseudo-terminal (the live line redrawn after every file).
The ratios to the first are the overhead, within the machine's noise; the drawing
alone is also timed in process.
"""

import argparse
import os
import pty
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section
from run_contours import EXE

ROOT = Path(__file__).resolve().parent.parent


def timed(args: list[str], terminal: bool) -> float:
    """Seconds of one whole process, its stderr on a pseudo-terminal or piped."""
    t0 = time.perf_counter()
    if not terminal:
        subprocess.run(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, check=True)
        return time.perf_counter() - t0
    master, slave = pty.openpty()
    p = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=slave)
    os.close(slave)
    while True:
        try:
            if not os.read(master, 1 << 16):
                break
        except OSError:
            break
    if p.wait():
        raise SystemExit(f"{args} failed")
    os.close(master)
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    ways = (("--no-progress", ["--no-progress"], False), ("piped", [], False),
            ("terminal", [], True))  # fmt: skip
    times = {name: [] for name, _, _ in ways}
    with tempfile.TemporaryDirectory() as d:
        src = Path(d) / "in"
        src.mkdir()
        csv = sorted((ROOT / "samples").glob("*.csv"))
        for k in range(50):
            shutil.copy(csv[k % len(csv)], src / f"{k:02d}_{csv[k % len(csv)].name}")
        for r in range(args.repeat):  # (the order turned each round: no way always first)
            for name, extra, terminal in ways[r % 3 :] + ways[: r % 3]:
                out = Path(d) / name
                cmd = [EXE, "all", str(src), "--out-dir", str(out), "-j", "2", "--force", *extra]
                times[name].append(timed(cmd, terminal))
    base = statistics.median(times["--no-progress"])
    lines = heading(
        f"## Progress on a batch: its cost (whole processes, median of {args.repeat})",
        "`python benchmarks/run_progress.py`: 50 contours (the samples' CSV files in turn), "
        "`deformesh all DIR --out-dir OUT -j 2` with `--no-progress`, with stderr piped "
        "(plain lines at every tenth) and with stderr on a pseudo-terminal (the live line "
        "redrawn after every file).",
    ) + ["| progress | s | ratio to none |", "| --- | ---: | ---: |"]
    for name, _, _ in ways:
        t = statistics.median(times[name])
        lines.append(f"| {name} | {t:.2f} | {t / base:.3f} |")
        print(lines[-1], file=sys.stderr)
    cost = drawing_cost()
    lines += [
        "",
        "The drawing alone, in process (`BatchProgress.step` 50 times, to a stream that "
        "says it is a terminal for the live line): "
        + ", ".join(f"{name} {1e3 * s:.2f} ms" for name, s in cost.items())
        + f", against {base:.2f} s for the batch: "
        + ", ".join(f"{name} {100 * s / base:.3f}%" for name, s in cost.items())
        + ". The whole processes' ratios above are within this machine's noise.",
    ]
    write_section("progress", "\n".join(lines))


def drawing_cost(files: int = 50, repeat: int = 20) -> dict:
    """Seconds the progress takes for a batch of ``files``: the median of ``repeat``."""
    import io

    from deformesh_cli.cli.progress import BatchProgress

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    out = {}
    for how in ("plain", "live"):
        runs = []
        for _ in range(repeat):
            old, sys.stderr = sys.stderr, Terminal()
            try:
                t0 = time.perf_counter()
                bar = BatchProgress(files, how)
                for k in range(files):
                    bar.step("ok", f"contour_{k:02d}.csv")
                bar.close()
                runs.append(time.perf_counter() - t0)
            finally:
                sys.stderr = old
        out[how] = statistics.median(runs)
    return out


if __name__ == "__main__":
    main()
