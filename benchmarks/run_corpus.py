"""Mesh the real corpus (tests/data/corpus) at default options, as one batch, ``--runs``
times; write the pass rate and the time per contour into benchmarks/RESULTS.md (section
"corpus"), each contour next to Triangle ``pq30Y`` on the same points (its triangles and
smallest angle): how many of our smallest angles are at least Triangle's, and our
triangles over Triangle's at the median.  Each contour's seconds are its least over the
runs, as timeit takes the least of its repeats: on these shared machines the same batch
took 21 to 33 s within an hour, and a contour's time moved by a third between runs;
every run's wall time and slowest contour are written too.

Usage: python benchmarks/run_corpus.py [--jobs N] [--runs N] [--max-nodes N]   (make bench)
       python benchmarks/run_corpus.py --records FILE --wall SECONDS  (format a run already
       made: FILE holds the batch's --json output)
"""

import argparse
import collections
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section
from run_contours import EXE, ROOT
from run_graded import triangle_run

CORPUS = ROOT / "tests" / "data" / "corpus"


def kind(name: str) -> str:
    return {"airfoil": "airfoils", "icon": "icons", "coast": "coastlines"}[name.split("_")[0]]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--max-nodes", type=int, default=None, help="default: deformesh's own")
    ap.add_argument("--runs", type=int, default=3, help="batches run; each contour's least")
    ap.add_argument("--records", help="the --json output of a batch run already made")
    ap.add_argument("--wall", type=float, default=0.0, help="with --records: its wall time")
    args = ap.parse_args()
    extra = ["--max-nodes", str(args.max_nodes)] if args.max_nodes else []
    if args.records:
        runs = [(Path(args.records).read_text(), args.wall)]
    else:
        runs = [run_batch(args.jobs, extra) for _ in range(max(1, args.runs))]
    # (the folder's SOURCES.md comes back as a file not meshed: not a contour)
    every = [
        [r for r in map(json.loads, out.splitlines()) if not r["input"].endswith(".md")]
        for out, _ in runs
    ]
    walls = [wall for _, wall in runs]
    recs = least(every)
    by = collections.defaultdict(list)
    for r in recs:
        by[kind(Path(r["input"]).name)].append(r)
    opts = " ".join(extra) or "default options"
    lines = heading(
        f"## Corpus: real contours, {opts}",
        f"`deformesh all tests/data/corpus --out-dir ... --jobs {args.jobs}` ({opts}); "
        f"{len(recs)} contours in {min(walls):.0f} s wall. Seconds are per contour, inside "
        "the batch (no start-up)"
        + (
            f", each the least of {len(runs)} runs of the batch; the runs took "
            + ", ".join(f"{w:.0f}" for w in walls)
            + " s wall, their slowest contour "
            + ", ".join(f"{max(r['seconds'] for r in rs):.2f}" for rs in every)
            + " s."
            if len(runs) > 1
            else "."
        ),
    ) + [
        "| kind | contours | meshed (contract ok) | refused | median s (meshed) | "
        "max s (meshed) | max s (refused) |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for k in sorted(by) + ["all"]:
        rs = recs if k == "all" else by[k]
        ok = [r["seconds"] for r in rs if r["status"] == "ok"]
        bad = [r["seconds"] for r in rs if r["status"] != "ok"]
        lines.append(
            f"| {k} | {len(rs)} | {len(ok)} ({100 * len(ok) / len(rs):.0f}%) | "
            f"{len(bad)} | {statistics.median(ok) if ok else 0:.2f} | "
            f"{max(ok, default=0):.2f} | {max(bad, default=0):.2f} |"
        )
    peers = {r["input"]: triangle_of(r["input"]) for r in recs}
    ok = [r for r in recs if r["status"] == "ok" and peers[r["input"]] is not None]
    wins = sum(r["min_angle"] >= peers[r["input"]]["min_angle"] for r in ok)
    ratio = [r["triangles"] / peers[r["input"]]["triangles"] for r in ok]
    clean = sum(r["extra_boundary_nodes"] == 0 for r in ok)
    fast = sum(r["seconds"] < 1.0 for r in ok)
    lines += [
        "",
        f"Next to Triangle `pq30Y` on the same points, of the {len(ok)} meshed: smallest "
        f"angle at least Triangle's on {wins} ({100 * wins / max(len(ok), 1):.0f}%); "
        f"triangles {statistics.median(ratio) if ratio else 0:.2f} times Triangle's at the "
        f"median; {clean} with no extra boundary node; {fast} under 1 s.",
        "",
        "| contour | status | seconds | nodes | triangles | extra | min angle | "
        "Triangle: triangles | min angle | reason |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in recs:
        why = (r["error"] or "").removeprefix(f"{r['input']}: ")[:110].replace("|", "/")
        angle = f"{r['min_angle']:.1f}" if r["min_angle"] is not None else ""
        extra = r["extra_boundary_nodes"] if r["extra_boundary_nodes"] is not None else ""
        t = peers[r["input"]]
        peer = f"{t['triangles']} | {t['min_angle']:.1f}" if t is not None else " | "
        lines.append(
            f"| {Path(r['input']).name} | {r['status']} | {r['seconds']:.2f} | "
            f"{r['nodes'] or ''} | {r['triangles'] or ''} | {extra} | {angle} | {peer} | "
            f"{why} |"
        )
    write_section("corpus", "\n".join(lines))
    print(
        f"corpus: {sum(r['status'] == 'ok' for r in recs)}/{len(recs)} meshed, "
        f"{' / '.join(f'{w:.0f}' for w in walls)} s; wrote benchmarks/RESULTS.md",
        file=sys.stderr,
    )


def triangle_of(path: str) -> dict | None:
    """Triangle ``pq30Y`` on the contour file's points (None if deformesh cannot read
    it: a contour it refuses as invalid)."""
    from deformesh_cli.errors import DeformeshError
    from deformesh_cli.readers import load_contour

    try:
        return triangle_run(load_contour(path))
    except DeformeshError:
        return None


def run_batch(jobs: int, extra: list[str]) -> tuple[str, float]:
    """One batch over the corpus: its ``--json`` lines and its wall time."""
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        p = subprocess.run(
            [EXE, "all", str(CORPUS), "--out-dir", d, "--jobs", str(jobs), "--json", "-q", *extra],
            capture_output=True,
            text=True,
        )
        return p.stdout, time.perf_counter() - t


def least(runs: list[list[dict]]) -> list[dict]:
    """The first run's records, each with its contour's least seconds over ``runs``; the
    runs must agree on every contour's status and nodes (the meshes are deterministic)."""
    out = []
    by_input = [{r["input"]: r for r in rs} for rs in runs]
    for r in runs[0]:
        same = [b.get(r["input"]) for b in by_input]
        if any(o is None or (o["status"], o["nodes"]) != (r["status"], r["nodes"]) for o in same):
            raise SystemExit(f"{r['input']}: the runs of the batch differ")
        out.append({**r, "seconds": min(o["seconds"] for o in same)})
    return out


if __name__ == "__main__":
    main()
