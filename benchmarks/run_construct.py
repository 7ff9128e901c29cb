"""The pipeline on the graded grid (``select/construct.py``), stage by stage,
on the random set (tests/random_polygons.py) or the corpus (tests/data/corpus, each
next to Triangle ``pq30Y`` on the same points): cut the sharp ears, select, deform
keeping folds, mend them, recover the boundary, add the ears back, run the quality
stage, check the contract and tests/independent.py.  In process, one case per
worker with a bound of ``--bound`` seconds each.  Writes the tally, the stage
times and every case that did not mesh into benchmarks/RESULTS.md (sections
"construct" and "construct-corpus").

Usage: python benchmarks/run_construct.py [--set random|corpus] [--count 60] [--jobs 2]
       [--bound 30]
"""

import argparse
import collections
import signal
import statistics
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def one(case, bound: float, growth: float | None = None) -> dict:
    from deformesh_cli import forced, pipeline, quality
    from deformesh_cli.readers import load_contour
    from tests.independent import contract_problems
    from tests.random_polygons import write_csv

    if isinstance(case, Path):
        from deformesh_cli.errors import InputError

        f = case
        name = f.name
        try:
            c = load_contour(f)
        except InputError as exc:  # (the corpus holds two invalid contours)
            return {"name": name, "n": 0, "outcome": "invalid", "why": str(exc)[-60:],
                    "times": {}, "s": 0.0}  # fmt: skip
        points, ring = c.points, c.ring
    else:
        name, points, ring = case
        f = Path(tempfile.mkdtemp()) / f"{name}.csv"
        write_csv(f, points, ring)
        c = load_contour(f)

    def up(*_):
        raise TimeoutError(f"over {bound:g} s")

    signal.signal(signal.SIGALRM, up)
    signal.setitimer(signal.ITIMER_REAL, bound)
    t0 = time.perf_counter()
    seconds: dict = {}
    rec = {"name": name, "n": c.n}
    try:
        kw = {} if growth is None else {"growth": growth}
        got = pipeline.mesh_contour(c, seconds=seconds, **kw)
        mesh = got.mesh
        problems = contract_problems(mesh.points, mesh.triangles, points, ring)
        if problems:
            raise RuntimeError(f"independent check: {problems[0]}")
        rec.update(
            outcome="ok",
            ears=got.report["ears"],
            extra=got.selection.extra_nodes,
            triangles=len(mesh.triangles),
            angle=float(quality.measures(mesh.points, mesh.triangles)[0].min()),
            under=int(forced.under_bound(mesh.points, mesh.triangles, mesh.lines)),
        )
        if isinstance(case, Path):
            from run_graded import triangle_run

            rec["triangle"] = triangle_run(c)
    except Exception as exc:  # (a benchmark records every outcome)
        why = str(exc).splitlines()[0].replace(f"{f}: ", "")
        rec.update(outcome=type(exc).__name__, why=why[:120])
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    rec["times"] = seconds
    rec["s"] = time.perf_counter() - t0
    return rec


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--set", choices=("random", "corpus"), default="random")
    ap.add_argument("--count", type=int, default=60)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--bound", type=float, default=30.0)
    ap.add_argument("--growth", type=float, default=None, help="default: deformesh's own")
    args = ap.parse_args()
    from tests.random_polygons import catalogue

    if args.set == "corpus":
        cases = sorted((ROOT / "tests" / "data" / "corpus").glob("*_*.*"))
        what = "the corpus (tests/data/corpus), each next to Triangle `pq30Y` on its points"
    else:
        cases = list(catalogue(args.count))
        what = f"the first {args.count} polygons of tests/random_polygons.py"
    with ProcessPoolExecutor(args.jobs) as pool:
        recs = list(pool.map(one, cases, [args.bound] * len(cases), [args.growth] * len(cases)))
    tally = collections.Counter(r["outcome"] for r in recs)
    ok = [r for r in recs if r["outcome"] == "ok"]
    lines = heading(
        f"## The graded grid's stages on the {args.set} set",
        f"`python benchmarks/run_construct.py --set {args.set}"
        + (f" --count {args.count}" if args.set == "random" else "")
        + (f" --growth {args.growth:g}" if args.growth else "")
        + f"`: {what} through `pipeline.mesh_contour` in process ({args.bound:g} s each "
        "at most), each stage timed.",
    )
    lines += [
        "Outcomes: " + ", ".join(f"{k} {v}" for k, v in sorted(tally.items())) + ".",
        "",
    ]
    if ok:
        total = sorted(r["s"] for r in ok)
        extra = sorted(r["extra"] for r in ok)
        lines += [
            f"Meshed: median {total[len(total) // 2]:.2f} s, slowest {total[-1]:.2f} s, "
            f"{sum(t < 1 for t in total)} under 1 s; "
            f"extra boundary nodes taken out: median {extra[len(extra) // 2]}, "
            f"most {extra[-1]}; {sum(r['ears'] > 0 for r in ok)} had ears cut; "
            f"smallest angle under 1 degree on {sum(r['angle'] < 1 for r in ok)}; "
            f"triangles under a third of what the boundary forces there "
            f"(`forced.under_bound`) on {sum(r['under'] > 0 for r in ok)}.",
            "",
        ]
    if args.set == "corpus" and ok:
        wins = sum(r["angle"] >= r["triangle"]["min_angle"] - 1e-9 for r in ok)
        ratio = statistics.median(r["triangles"] / r["triangle"]["triangles"] for r in ok)
        lines += [
            f"Smallest angle at least Triangle's on {wins} of {len(ok)}; triangles "
            f"{ratio:.2f} times Triangle's at the median.",
            "",
            "| contour | points | s | triangles | Triangle's | smallest angle | Triangle's |",
            "|---|---:|---:|---:|---:|---:|---:|",
        ]
        for r in ok:
            t = r["triangle"]
            lines.append(
                f"| {r['name']} | {r['n']} | {r['s']:.2f} | {r['triangles']} | "
                f"{t['triangles']} | {r['angle']:.1f} | {t['min_angle']:.1f} |"
            )
        lines.append("")
    lines += ["| polygon | points | outcome | s | stages (s) |", "|---|---|---|---|---|"]
    for r in recs:
        if r["outcome"] == "ok":
            continue
        stages = ", ".join(f"{n} {x:.2f}" for n, x in r["times"].items())
        lines.append(
            f"| {r['name']} | {r['n']} | {r['outcome']}: {r['why']} | {r['s']:.1f} | {stages} |"
        )
    write_section("construct" if args.set == "random" else "construct-corpus", "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
