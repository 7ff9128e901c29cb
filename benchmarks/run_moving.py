"""Moving meshes: time and quality of ``deformesh move`` per case.

Usage: python benchmarks/run_moving.py [--repeat N]   (make bench)

For each case: ``deformesh all`` makes the mesh once, then ``deformesh move``
runs as a whole process N times (median): seconds, peak RSS, and from its
--json the smallest angle over all frames next to frame 0's, the solves and
step halvings.  Cases: the two README samples, the pitching airfoil of 160
points in a larger box (more triangles), a non-rigid motion of that airfoil
(stretched and thickened) on the whole mesh and on a band, and a hole turning
inside a square that stays put (each ring its own rigid motion).
"""

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
from make_samples import naca0012, pitching, pulsating
from results import heading, write_section
from run_contours import EXE, REFERENCE, ROOT, run_process

SAMPLES = ROOT / "samples"


def frames_to(folder: Path, frames: list[np.ndarray], ring=None) -> list[str]:
    """Write frames as CSV files (with a ``ring`` column if given); their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for k, pts in enumerate(frames, start=1):
        f = folder / f"frame_{k:02d}.csv"
        if ring is None:
            np.savetxt(f, pts, delimiter=",", header="x,y", comments="", fmt="%.17g")
        else:
            np.savetxt(
                f,
                np.column_stack([pts, ring]),
                delimiter=",",
                header="x,y,ring",
                comments="",
                fmt=["%.17g", "%.17g", "%d"],
            )
        out.append(str(f))
    return out


def turning_hole(frames: int = 20, degrees: float = 10.0):
    """square_hole_100 with its hole turned by ``degrees * k / frames`` in frame k
    (the square stays); the frames and the ring column."""
    rows = np.loadtxt(REFERENCE / "square_hole_100.csv", delimiter=",", skiprows=1)
    pts, ring = rows[:, :2], rows[:, 2].astype(int)
    hole = ring == 1
    centre = pts[hole].mean(axis=0)
    out = []
    for k in range(1, frames + 1):
        a = np.radians(degrees * k / frames)
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        p = pts.copy()
        p[hole] = (pts[hole] - centre) @ rot.T + centre
        out.append(p)
    return out, ring


def body_in_a_box(frames: int = 10):
    """An ellipse (semi-axes 0.3 and 0.12, 48 points) shifted by 0.08 and turned 9
    degrees a frame, for a far field in the box -1..2 x -1..1: its frames."""
    t = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    p = np.column_stack([0.3 * np.cos(t), 0.12 * np.sin(t)])
    out = []
    for k in range(1, frames + 1):
        a = np.radians(9 * k)
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        out.append(p @ rot.T + [0.08 * k, 0.0])
    return p, out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        base160 = naca0012(160)
        np.savetxt(
            d / "naca160.csv", base160, delimiter=",", header="x,y", comments="", fmt="%.17g"
        )
        box = ["--exterior", "--box=-2,-2,3,2"]
        pulse = frames_to(d / "pulse160", pulsating(base160, amplitude=0.1))
        turned, ring = turning_hole()
        body, moved = body_in_a_box()
        np.savetxt(d / "body.csv", body, delimiter=",", header="x,y", comments="", fmt="%.17g")
        carried = frames_to(d / "body", moved)
        far = ["--exterior", "--box=-1,-1,2,1"]
        cases = [
            (
                "pitching sample (README)",
                SAMPLES / "pitching" / "naca0012_80.csv",
                ["--exterior", "--box=-1.5,-1.5,2.5,1.5"],
                sorted(str(p) for p in (SAMPLES / "pitching").glob("frame_*.csv")),
                [],
            ),
            (
                "pulsating peanut (README)",
                SAMPLES / "peanut.csv",
                [],
                sorted(str(p) for p in (SAMPLES / "pulsating").glob("frame_*.csv")),
                [],
            ),
            (
                "pitching NACA 0012, 160 points, box -2..3",
                d / "naca160.csv",
                box,
                frames_to(d / "pitch160", pitching(base160)),
                [],
            ),
            (
                "pulsating NACA 0012 (amplitude 0.1), whole mesh, --min-angle 0",
                d / "naca160.csv",
                box,
                pulse,
                ["--min-angle", "0"],
            ),
            (
                "pulsating NACA 0012 (amplitude 0.1), --solve band, --min-angle 0",
                d / "naca160.csv",
                box,
                pulse,
                ["--solve", "band", "--min-angle", "0"],
            ),
            (
                "pulsating NACA 0012 (amplitude 0.1), --remesh",
                d / "naca160.csv",
                box,
                pulse,
                ["--remesh"],
            ),
            (
                "ellipse in a box, 0.08 and 9 degrees a frame, --min-angle 0",
                d / "body.csv",
                far,
                carried,
                ["--min-angle", "0"],
            ),
            (
                "ellipse in a box, 0.08 and 9 degrees a frame, --remesh",
                d / "body.csv",
                far,
                carried,
                ["--remesh"],
            ),
            (
                "square_hole_100, the hole turning 10 degrees",
                REFERENCE / "square_hole_100.csv",
                [],
                frames_to(d / "hole", turned, ring),
                [],
            ),
        ]
        for name, contour, mesh_opts, frames, move_opts in cases:
            mesh = d / "mesh.vtu"
            _, _, code, _, err = run_process(
                [EXE, "all", str(contour), "-o", str(mesh), "-q", *mesh_opts]
            )
            if code:
                raise SystemExit(f"{name}: {err}")
            times, rss, rec = [], [], None
            for _ in range(args.repeat):
                dt, mb, code, text, err = run_process(
                    [
                        EXE,
                        "move",
                        str(mesh),
                        *frames,
                        "--out-dir",
                        str(d / "out"),
                        "--json",
                        "-q",
                        *move_opts,
                    ]
                )
                if code:
                    raise SystemExit(f"{name}: {err}")
                times.append(dt)
                rss.append(mb)
                rec = json.loads(text)
            per = rec["per_frame"][1:]
            rows.append(
                (
                    name,
                    rec,
                    statistics.median(times),
                    statistics.median(rss),
                    sum(r["solves"] for r in per),
                    sum(r["halvings"] for r in per),
                )
            )
            print(
                f"{name}: {statistics.median(times):.2f} s, min angle "
                f"{rec['min_angle']:.1f} (frame 0 {rec['min_angle_first']:.1f})",
                file=sys.stderr,
            )
    lines = heading(
        f"## Moving meshes: deformesh move (whole processes, median of {args.repeat})",
        "`deformesh all` makes the mesh once; then `deformesh move MESH FRAME... --out-dir` "
        "(20 frames, `.vtu` and `.pvd`) is timed as a whole process. Min angle over all "
        "frames next to frame 0's; solves and step halvings summed over the frames (no "
        "solve where the rigid motion alone reaches the frame). Under the default floor "
        "(`--min-angle 2`) a frame whose smallest angle falls under 2 degrees stops the "
        "run; the rows with `--min-angle 0` measure how far the angles fall without one, "
        "the rows with `--remesh` mesh such a frame afresh (frames listed).",
    ) + [
        "| case | triangles | frames | seconds | s per frame | peak RSS MB | min angle frame 0 "
        "| min angle all frames | worst frame | solves | halvings | meshed afresh |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for name, rec, sec, mb, solves, halvings in rows:
        n = rec["frames"] - 1
        again = ", ".join(map(str, rec["remeshed_frames"])) or "-"
        lines.append(
            f"| {name} | {rec['triangles']} | {n} | {sec:.2f} | {sec / n:.3f} | "
            f"{mb:.0f} | {rec['min_angle_first']:.1f} | {rec['min_angle']:.1f} | "
            f"{rec['min_angle_frame']} | {solves} | {halvings} | {again} |"
        )
    lines += ["", "Each frame's smallest angle (degrees), frame 0 first:", ""]
    for name, rec, *_ in rows:
        if name.startswith("ellipse"):
            angles = " ".join(f"{r['min_angle']:.2f}" for r in rec["per_frame"])
            lines.append(f"- {name}: {angles}")
    write_section("moving", "\n".join(lines))


if __name__ == "__main__":
    main()
