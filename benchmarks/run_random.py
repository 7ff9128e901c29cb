"""Mesh 300 random hostile contours (tests/random_polygons.py: jagged angle-sorted
clouds, uneven stars, clusters, spikes, combs, near-touching parts, holes near the
outline; 10 to 500 points) with ``deformesh all`` at default options, one process
each.  Each must answer within its time bound (deformesh's search bound,
:func:`deformesh_cli.deadline.search_bound`, plus :data:`SLACK`): a mesh that
passes an independent contract check (tests/independent.py, numpy and shapely
only), or a one-line refusal (exit 1).
Writes the tally and the slowest answers into benchmarks/RESULTS.md (section
"random").

Usage: python benchmarks/run_random.py [--count 300] [--jobs 2] [--seed 0]
"""

import argparse
import collections
import json
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import meshio

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section
from run_contours import EXE, ROOT

sys.path.insert(0, str(ROOT))
from deformesh_cli.deadline import search_bound
from tests.independent import contract_problems
from tests.random_polygons import catalogue, write_csv

#: What a process start, finishing a selection found and writing the answer may add to
#: the search's bound (seconds).
SLACK = 10.0


def one(case, folder: Path) -> dict:
    name, points, ring = case
    f = folder / f"{name}.csv"
    write_csv(f, points, ring)
    out = folder / f"{name}.msh"
    bound = search_bound(len(points)) + SLACK
    t = time.perf_counter()
    try:
        p = subprocess.run(
            [EXE, "all", str(f), "-o", str(out), "--json", "-q"],
            capture_output=True,
            text=True,
            timeout=2 * bound,
        )
    except subprocess.TimeoutExpired:
        return {"name": name, "n": len(points), "outcome": "no answer", "s": 2 * bound}
    s = time.perf_counter() - t
    rec = {"name": name, "n": len(points), "s": s, "bound": bound}
    lines = p.stderr.strip().splitlines()
    if p.returncode == 0:
        m = meshio.read(out)
        problems = contract_problems(m.points, m.cells_dict["triangle"], points, ring)
        info = json.loads(p.stdout)
        rec.update(
            outcome="meshed" if not problems else "BROKEN: " + "; ".join(problems),
            extra=info["extra_boundary_nodes"],
            angle=info["min_angle"],
        )
    elif p.returncode == 1 and len(lines) == 1 and "Traceback" not in p.stderr:
        rec.update(outcome="refused", why=lines[0])
    else:
        rec.update(outcome=f"BAD EXIT {p.returncode}", why=p.stderr[-300:])
    if s > bound:
        rec["outcome"] += " (late)"
    return rec


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--count", type=int, default=300)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", help="also write every record to this file")
    args = ap.parse_args()
    cases = catalogue(args.count, seed=args.seed)
    with tempfile.TemporaryDirectory() as d, ThreadPoolExecutor(args.jobs) as pool:
        t = time.perf_counter()
        recs = list(pool.map(lambda c: one(c, Path(d)), cases))
        wall = time.perf_counter() - t
    if args.json:
        Path(args.json).write_text(json.dumps(recs, indent=1))
    tally = collections.Counter(r["outcome"].split(":")[0] for r in recs)
    kinds = collections.defaultdict(collections.Counter)
    for r in recs:
        kinds[r["name"].split("-", 1)[1].rsplit("-", 1)[0]][r["outcome"].split(":")[0]] += 1
    rows = [
        "| kind | contours | meshed | refused | other |",
        "|---|---|---|---|---|",
    ]
    for k, c in kinds.items():
        other = sum(c.values()) - c["meshed"] - c["refused"]
        rows.append(f"| {k} | {sum(c.values())} | {c['meshed']} | {c['refused']} | {other} |")
    slow = sorted(recs, key=lambda r: -r["s"])[:8]
    meshed = [r for r in recs if r["outcome"] == "meshed"]
    text = "\n".join(
        [
            *heading("random", f"{args.count} random hostile contours (seed {args.seed})"),
            f"`python benchmarks/run_random.py --count {args.count} --jobs {args.jobs}`: "
            f"one `deformesh all` process per contour, default options, wall {wall:.0f} s. "
            "Each answer is a mesh that passes tests/independent.py or a one-line "
            f"refusal, within `search_bound(points)` + {SLACK:g} s.",
            "",
            "Outcomes: " + ", ".join(f"{k} {v}" for k, v in sorted(tally.items())),
            "",
            *rows,
            "",
            f"Meshed with zero extra boundary nodes: "
            f"{sum(1 for r in meshed if r['extra'] == 0)} of {len(meshed)}.",
            "",
            "Slowest answers:",
            "",
            "| contour | points | seconds | bound | outcome |",
            "|---|---|---|---|---|",
            *(
                f"| {r['name']} | {r['n']} | {r['s']:.1f} | {r.get('bound', 0):.0f} | "
                f"{r['outcome'][:60]} |"
                for r in slow
            ),
        ]
    )
    write_section("random", text)
    print(text)
    bad = [r for r in recs if r["outcome"] not in ("meshed", "refused")]
    for r in bad:
        print("NOT ANSWERED WELL:", r, file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
