"""Fuzz the command line with mutated state files, contours and output paths.

    python scripts/fuzz_hostile.py [--runs N] [--seed S] [--jobs J] [--keep DIR]

Each run is a whole ``deformesh`` process, as a user starts it, on one mutated
input:

- **states**: what ``select`` and ``deform`` write for the samples, on both grids,
  with one to three random changes: a ``meta.json`` value replaced (by a number,
  a huge or tiny one, NaN, a string with control characters, null, a list, a long
  whole number), a field added or removed, an array's values changed, its dtype or
  shape changed, a member recompressed, or bytes of the archive flipped;
- **contours**: the sample CSV, SVG and GeoJSON files with bytes flipped, numbers
  replaced (huge, tiny, NaN, 400 digits), lines dropped or doubled;
- **outputs**: ``all`` and ``triangulate`` with ``-o``, ``--png`` and formats whose
  paths are the input, each other, links to an input or to a victim file, an
  existing sidecar of another program, or a full or closed stdout.

A run passes when it ends with exit 0, 1 or 2; with exit 1, stderr is one line
starting ``deformesh: error: ``; with exit 2, one ``Error:`` line; never a
``Traceback`` or a signal; no file that existed before (inputs, victims, other
programs' sidecars) changed unless the run named it as its output and exited 0;
no file left besides the outputs of a successful run.  Prints the counts per
kind and exit code, and each failing run (its command and stderr); exits 1 if
any run failed.  The same seed gives the same runs.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import zipfile
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "samples"
EXE = str(Path(sys.executable).parent / "deformesh")
CONTOURS = ["circle.csv", "peanut.csv", "half_disk.csv", "bracket.svg"]

ODD_VALUES = [
    0, -1, 1, 2**63, 10**400, 1e308, -1e308, 1e-308, float("nan"), float("inf"),
    "", "x\nTraceback (most recent call last):\x1b[2J", None, [], [1, 2], {"a": 1},
    True, "graded", 3.5, "1/0", "-1", "d - d",
]  # fmt: skip


def _sha(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None
    except OSError:
        return None


def _run(args: list[str], cwd: Path, stdin=None, shell_tail: str = "") -> tuple[int, str]:
    if shell_tail:
        line = " ".join(f"'{a}'" for a in [EXE, *args]) + " " + shell_tail
        r = subprocess.run(["bash", "-c", line], cwd=cwd, capture_output=True, timeout=300)
    else:
        r = subprocess.run([EXE, *args], cwd=cwd, capture_output=True, timeout=300, stdin=stdin)
    return r.returncode, r.stderr.decode("utf-8", "replace")


def _judge(code: int, err: str, quiet: bool) -> str | None:
    """What is wrong with a run's ending, or None."""
    if code not in (0, 1, 2):
        return f"exit code {code}"
    if any(ln.startswith("Traceback") for ln in err.splitlines()):
        return "a traceback"
    lines = err.splitlines()
    if code == 1:
        errors = [ln for ln in lines if ln.startswith("deformesh: error: ")]
        others = [ln for ln in lines if not ln.startswith("deformesh: ")]
        if len(errors) != 1 or others:
            return f"{len(lines)} lines on stderr for exit 1"
    if code == 2 and sum(ln.startswith("Error:") for ln in lines) != 1:
        return "not one Error: line for exit 2"
    if code == 0 and quiet and err:
        return "a message under -q"
    return None


# ---------------------------------------------------------------- states


def _states(work: Path) -> dict[str, bytes]:
    out = {}
    for name in ("circle.csv", "bracket.svg"):
        for grid in ("graded", "uniform"):
            sel, dfm = work / f"{name}.{grid}.sel", work / f"{name}.{grid}.def"
            subprocess.run([EXE, "select", SAMPLES / name, "--grid", grid, "-o", sel, "-q"],
                           check=True)  # fmt: skip
            subprocess.run([EXE, "deform", sel, "-o", dfm, "-q"], check=True)
            out[f"{name}.{grid}.selected"] = sel.read_bytes()
            out[f"{name}.{grid}.deformed"] = dfm.read_bytes()
    return out


def _paths(d, prefix=""):
    for k, v in d.items():
        yield prefix + k
        if isinstance(v, dict):
            yield from _paths(v, prefix + k + ".")


def _mutate_state(data: bytes, rng: random.Random) -> bytes:
    zf = zipfile.ZipFile(io.BytesIO(data))
    members = {n: zf.read(n) for n in zf.namelist()}
    methods = dict.fromkeys(members, zipfile.ZIP_STORED)
    meta = json.loads(members["meta.json"])
    for _ in range(rng.randint(1, 3)):
        kind = rng.choice(["meta", "meta", "add", "drop", "array", "dtype", "shape",
                           "compress", "flip"])  # fmt: skip
        if kind in ("meta", "drop"):
            path = rng.choice(list(_paths(meta)))
            *head, last = path.split(".")
            d = meta
            for k in head:
                d = d[k]
            if kind == "drop":
                del d[last]
            else:
                d[last] = rng.choice(ODD_VALUES)
        elif kind == "add":
            where = rng.choice([meta, meta["grid"], meta["options"]])
            where[rng.choice(["top", "kind", "size", "size_field", "x", "max_nodes"])] = rng.choice(
                ODD_VALUES
            )
        elif kind in ("array", "dtype", "shape"):
            names = [n for n in members if n.endswith(".npy")]
            n = rng.choice(names)
            a = np.lib.format.read_array(io.BytesIO(members[n]))
            if kind == "array" and a.size:
                a = a.copy()
                k = rng.randrange(a.size)
                flat = a.reshape(-1)
                if a.dtype.kind in "iu":  # (wrapped to the array's integer type)
                    value = np.array(rng.choice([0, -1, 1, 2**31, 255])).astype(a.dtype)
                else:
                    value = rng.choice([np.nan, np.inf, 1e300, -1e300, 0.0, 1e-300])
                flat[k] = value
            elif kind == "dtype":
                a = a.astype(rng.choice([np.float32, np.int8, np.complex128, bool, np.uint64]))
            else:
                a = rng.choice([a[:-1], np.concatenate([a, a[:1]]), a.reshape(-1), a[::-1]])
            b = io.BytesIO()
            np.lib.format.write_array(b, np.ascontiguousarray(a))
            members[n] = b.getvalue()
        elif kind == "compress":
            methods[rng.choice(list(members))] = rng.choice(
                [zipfile.ZIP_DEFLATED, zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA]
            )
    members["meta.json"] = json.dumps(meta).encode()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as out:
        for n, b in members.items():
            out.writestr(n, b, methods[n])
    data = bytearray(buf.getvalue())
    if rng.random() < 0.15:  # bytes of the archive flipped
        for _ in range(rng.randint(1, 8)):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
    return bytes(data)


def _state_run(k: int, data: bytes, stage: str, work: Path, rng: random.Random):
    d = work / f"s{k}"
    d.mkdir()
    src = d / "in.state"
    src.write_bytes(_mutate_state(data, rng))
    if stage == "selected":
        named = [d / "out.state"]
        args = ["deform", str(src), "-o", str(named[0]), "-q"]
    else:
        named = [d / "out.vtk", d / "o.png"]
        args = ["triangulate", str(src), "-o", str(named[0]), "--png", str(named[1]), "-q"]
    return d, args, [src], named


# ---------------------------------------------------------------- contours


def _mutate_text(data: bytes, rng: random.Random) -> bytes:
    kind = rng.choice(["flip", "number", "lines", "number", "cut"])
    if kind == "flip":
        b = bytearray(data)
        for _ in range(rng.randint(1, 6)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        return bytes(b)
    if kind == "cut":
        return data[: rng.randrange(len(data))]
    text = data.decode("utf-8", "replace")
    if kind == "lines":
        lines = text.splitlines(keepends=True)
        k = rng.randrange(len(lines))
        lines.insert(k, lines[k]) if rng.random() < 0.5 else lines.pop(k)
        return "".join(lines).encode()
    import re

    nums = [m.group(0) for m in re.finditer(r"-?\d+\.?\d*(e-?\d+)?", text)]
    for old in rng.sample(nums, min(len(nums), rng.randint(1, 3))):
        new = rng.choice(["1e308", "1e-308", "nan", "inf", "1" * 400, "1e9", "1e-9", "0"])
        text = text.replace(old, new, 1)
    return text.encode()


def _contour_run(k: int, name: str, work: Path, rng: random.Random):
    d = work / f"c{k}"
    d.mkdir()
    data = (SAMPLES / name).read_bytes()
    if rng.random() < 0.3 and name.endswith(".csv"):  # as GeoJSON
        pts = np.genfromtxt(SAMPLES / name, delimiter=",", comments="#")
        pts = pts[np.isfinite(pts).all(axis=1)][:, :2]
        ring = pts.tolist() + [pts[0].tolist()]
        data = json.dumps({"type": "Polygon", "coordinates": [ring]}).encode()
        name = name.replace(".csv", ".geojson")
    src = d / name
    src.write_bytes(_mutate_text(data, rng))
    named = [d / "out.msh", d / "o.png"]
    args = ["all", str(src), "-o", str(named[0]), "--png", str(named[1]), "-q"]
    return d, args, [src], named


# ---------------------------------------------------------------- output paths


def _output_run(k: int, work: Path, rng: random.Random):
    d = work / f"o{k}"
    d.mkdir()
    src = d / "in.csv"
    shutil.copy(SAMPLES / "circle.csv", src)
    victim = d / "victim.txt"
    victim.write_text("a file of the user's")
    foreign = d / "m.h5"
    foreign.write_text("another program's data")
    (d / "link-in.vtk").symlink_to(src)
    (d / "link-victim.h5").symlink_to(victim)
    (d / "hard.vtk").hardlink_to(src)
    choices = ["m.vtk", "m.xdmf", "in.csv", "link-in.vtk", "hard.vtk", "victim.txt",
               "link-victim.xdmf", "m.png", "-"]  # fmt: skip
    out = rng.choice(choices)
    png = rng.choice([None, "m.png", "m.vtk", "in.csv", "link-in.vtk", "victim.txt"])
    args = ["all", str(src), "-o", out if out == "-" else str(d / out), "-q"]
    if out == "-" or out == "victim.txt":
        args += ["--format", "vtk"]
    if png is not None:
        args += ["--png", str(d / png)]
    if rng.random() < 0.2:
        args.append("--force")
    tail = rng.choice(["", "", "> /dev/full", ">&-", "> /dev/null"]) if out == "-" else ""
    named = [] if out == "-" else [d / out]
    if png is not None:
        named.append(d / png)
    return d, args, [src], named, tail


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=300, help="runs in all (default 300)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--keep", type=Path, default=None, help="keep the work folder here")
    a = ap.parse_args()
    rng = random.Random(a.seed)
    work = Path(tempfile.mkdtemp(prefix="fuzz.")) if a.keep is None else a.keep
    work.mkdir(parents=True, exist_ok=True)
    states = _states(work)
    plans = []
    for k in range(a.runs):
        r = random.Random(rng.random())
        kind = ["state", "contour", "output"][k % 3]
        if kind == "state":
            key = r.choice(sorted(states))
            d, args, inputs, named = _state_run(k, states[key], key.split(".")[-1], work, r)
            tail = ""
        elif kind == "contour":
            d, args, inputs, named = _contour_run(k, r.choice(CONTOURS), work, r)
            tail = ""
        else:
            d, args, inputs, named, tail = _output_run(k, work, r)
        plans.append((kind, d, args, named, tail))

    def one(plan):
        kind, d, args, named, tail = plan
        before = {p: _sha(p) for p in d.iterdir() if not p.is_symlink()}
        try:
            code, err = _run(args, d, subprocess.DEVNULL, tail)
        except subprocess.TimeoutExpired:
            return kind, "timeout", "over 300 s", args, ""
        problem = _judge(code, err, "-q" in args)
        named = named + [p.with_suffix(".h5") for p in named if p.suffix == ".xdmf"]
        targets = {Path(os.path.realpath(p)) for p in named}
        for p, h in before.items():
            changed = _sha(p) != h
            if changed and not (code == 0 and Path(os.path.realpath(p)) in targets):
                problem = problem or f"{p.name} changed"
        after = {p for p in d.iterdir() if not p.is_symlink()} - set(before)
        extra = [p.name for p in after if code != 0 or p not in named]
        if extra:
            problem = problem or f"left {extra}"
        return kind, code, problem, args, err

    counts: Counter = Counter()
    failures = []
    with ThreadPoolExecutor(a.jobs) as pool:
        for kind, code, problem, args, err in pool.map(one, plans):
            counts[kind, code] += 1
            if problem:
                failures.append((problem, args, err))
    for (kind, code), n in sorted(counts.items(), key=str):
        print(f"{kind:8} exit {code}: {n}")
    print(f"{sum(counts.values())} runs, {len(failures)} failed (seed {a.seed}, work {work})")
    for problem, args, err in failures:
        print(f"FAIL {problem}: deformesh {' '.join(args)}\n{err}")
    if a.keep is None:
        shutil.rmtree(work, ignore_errors=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
