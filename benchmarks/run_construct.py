"""The constructed graded selection (``select/construct.py``, not yet the pipeline's)
on the random set (tests/random_polygons.py): cut the sharp ears, select, deform
keeping folds, mend them, recover the boundary, add the ears back, run the quality
stage, check the contract and tests/independent.py.  In process, one case per
worker with a bound of ``--bound`` seconds each.  Writes the tally, the stage
times and every case that did not mesh into benchmarks/RESULTS.md (section
"construct").

Usage: python benchmarks/run_construct.py [--count 60] [--jobs 2] [--bound 30]
"""

import argparse
import collections
import signal
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results import heading, write_section

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

STAGES = ("select", "deform", "mend", "recover", "improve")


def one(case, bound: float) -> dict:
    from deformesh_cli import improve, pipeline, quality, triangulate, untangle
    from deformesh_cli.options import MeshOptions
    from deformesh_cli.readers import load_contour
    from deformesh_cli.recover import recover
    from deformesh_cli.select import construct
    from tests.independent import contract_problems
    from tests.random_polygons import write_csv

    name, points, ring = case
    f = Path(tempfile.mkdtemp()) / f"{name}.csv"
    write_csv(f, points, ring)
    c = load_contour(f)

    def up(*_):
        raise TimeoutError(f"over {bound:g} s")

    signal.signal(signal.SIGALRM, up)
    signal.setitimer(signal.ITIMER_REAL, bound)
    t = [time.perf_counter()]
    rec = {"name": name, "n": c.n}
    try:
        grid_contour, kept, ears = construct.cut_ears(c)
        sel = construct.select_constructed(grid_contour)
        t.append(time.perf_counter())
        d = pipeline.run_deform(grid_contour, sel, MeshOptions(), keep_folds=True)
        t.append(time.perf_counter())
        cut = triangulate.cut(grid_contour, sel)
        placed = triangulate.place(grid_contour, sel, cut, d.points, folded=True)
        mended = untangle.untangle(placed, untangle.most_tangled(placed))
        t.append(time.perf_counter())
        if mended is None:
            raise RuntimeError("the folds were not mended")
        mesh, _ = recover(mended)
        mesh = construct.restore_ears(mesh, c, kept, ears)
        t.append(time.perf_counter())
        mesh, _ = improve.improve(mesh)
        t.append(time.perf_counter())
        quality.check_contract(mesh, c)
        problems = contract_problems(mesh.points, mesh.triangles, points, ring)
        if problems:
            raise RuntimeError(f"independent check: {problems[0]}")
        rec.update(
            outcome="ok",
            ears=len(ears),
            extra=sel.extra_nodes,
            triangles=len(mesh.triangles),
            angle=float(quality.measures(mesh.points, mesh.triangles)[0].min()),
        )
    except Exception as exc:  # (a benchmark records every outcome)
        why = str(exc).splitlines()[0].replace(f"{f}: ", "")
        rec.update(outcome=type(exc).__name__, why=why[:120])
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
    rec["times"] = [b - a for a, b in zip(t, t[1:])]
    rec["s"] = time.perf_counter() - t[0]
    return rec


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--count", type=int, default=60)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--bound", type=float, default=30.0)
    args = ap.parse_args()
    from tests.random_polygons import catalogue

    cases = list(catalogue(args.count))
    with ProcessPoolExecutor(args.jobs) as pool:
        recs = list(pool.map(one, cases, [args.bound] * len(cases)))
    tally = collections.Counter(r["outcome"] for r in recs)
    ok = [r for r in recs if r["outcome"] == "ok"]
    lines = heading(
        "## The constructed selection on the random set",
        f"`python benchmarks/run_construct.py --count {args.count}`: the first "
        f"{args.count} polygons of tests/random_polygons.py through the construction "
        f"in process ({args.bound:g} s each at most), not yet what `deformesh all` runs.",
    )
    lines += [
        "Outcomes: " + ", ".join(f"{k} {v}" for k, v in sorted(tally.items())) + ".",
        "",
    ]
    if ok:
        total = sorted(r["s"] for r in ok)
        extra = sorted(r["extra"] for r in ok)
        lines += [
            f"Meshed: median {total[len(total) // 2]:.2f} s, slowest {total[-1]:.2f} s; "
            f"extra boundary nodes taken out: median {extra[len(extra) // 2]}, "
            f"most {extra[-1]}; {sum(r['ears'] > 0 for r in ok)} had ears cut; "
            f"smallest angle under 1 degree on {sum(r['angle'] < 1 for r in ok)}.",
            "",
        ]
    lines += ["| polygon | points | outcome | s | stages (s) |", "|---|---|---|---|---|"]
    for r in recs:
        if r["outcome"] == "ok":
            continue
        stages = ", ".join(f"{n} {x:.2f}" for n, x in zip(STAGES, r["times"]))
        lines.append(
            f"| {r['name']} | {r['n']} | {r['outcome']}: {r['why']} | {r['s']:.1f} | {stages} |"
        )
    write_section("construct", "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
