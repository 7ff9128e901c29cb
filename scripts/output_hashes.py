"""Hash every file deformesh writes for the samples, to show a refactoring changed no output.

    python scripts/output_hashes.py --write scripts/output_hashes.json   # record
    python scripts/output_hashes.py --check scripts/output_hashes.json   # compare

Each sample (samples/*.csv, samples/*.svg and the first contour of each moving
sample) is meshed by ``deformesh all`` once per output format, and put through
``deformesh select`` and ``deformesh deform`` (the state files); each sample's
``.vtu`` mesh is put through ``deformesh adapt`` with a ring monitor.  The files'
sha256 are compared with the record; ``--check`` exits 1 and names each file
that differs.  The HDF5 sidecar of ``.xdmf`` holds creation times, so for it
the datasets' bytes are hashed instead of the file.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "samples"

#: (file suffix, extra options)
OUTPUTS = [
    ("vtk", []),
    ("vtu", []),
    ("msh", []),
    ("4.1.msh", ["--msh-version", "4.1"]),
    ("obj", []),
    ("ply", []),
    ("su2", []),
    ("xdmf", []),
]

#: The paper's form, which must not change as the default meshing does: the uniform
#: grid (extra boundary nodes kept), in .vtk, for every sample it can mesh.
UNIFORM = ("uniform.vtk", ["--grid", "uniform"])
#: Samples the uniform grid refuses (their spacing varies too much for one step).
NOT_UNIFORM = {"naca0012_cosine"}

#: Samples not put through ``adapt``: the ring through the middle of the cascade's box
#: runs along its blade, and adapt refuses that monitor there as too steep.
NO_ADAPT = {"cascade"}

#: ``adapt``'s monitor: a ring around each sample's centre of mass (in its own units).
RING = "1 + 10 * (1 - tanh(30 * ((x - {x:.3f})**2 + (y - {y:.3f})**2 - {r:.4f}))**2)"


def samples() -> list[Path]:
    found = sorted(SAMPLES.glob("*.csv")) + sorted(SAMPLES.glob("*.svg"))
    return found + [
        SAMPLES / "pitching" / "naca0012_80.csv",
        SAMPLES / "pulsating" / "frame_01.csv",
    ]


def exe() -> str:
    here = Path(sys.executable).parent / "deformesh"
    return str(here) if here.exists() else shutil.which("deformesh")


def digest(path: Path) -> str:
    if path.suffix == ".h5":
        import h5py

        h = hashlib.sha256()

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                h.update(name.encode())
                h.update(obj[()].tobytes())

        with h5py.File(path, "r") as f:
            f.visititems(visit)
        return "datasets:" + h.hexdigest()
    return hashlib.sha256(path.read_bytes()).hexdigest()


def jobs(out: Path) -> list[tuple[str, list[str]]]:
    """(name of the output, the deformesh command that writes it) for every output."""
    todo = []
    for src in samples():
        stem = f"{src.parent.name}_{src.stem}" if src.parent != SAMPLES else src.stem
        outputs = OUTPUTS + ([UNIFORM] if stem not in NOT_UNIFORM else [])
        for suffix, extra in outputs:
            name = f"{stem}.{suffix}"
            todo.append((name, ["all", str(src), "-o", str(out / name), "-q", *extra]))
        sel, dfm = out / f"{stem}.selected", out / f"{stem}.deformed"
        todo.append((sel.name, ["select", str(src), "-o", str(sel), "-q"]))
        todo.append((dfm.name, ["deform", str(sel), "-o", str(dfm), "-q"]))
        if stem not in NO_ADAPT:
            todo.append((f"{stem}.adapted.vtu", ["adapt", str(out / f"{stem}.vtu")]))
    return todo


def ring(mesh: Path) -> str:
    """A ring monitor through the middle of ``mesh``'s extent."""
    import meshio

    p = meshio.read(mesh).points[:, :2]
    lo, hi = p.min(axis=0), p.max(axis=0)
    x, y = (lo + hi) / 2
    return RING.format(x=x, y=y, r=(float((hi - lo).min()) / 4) ** 2)


def run_all(out: Path) -> dict[str, str]:
    todo = jobs(out)
    # the state files in order (deform reads select's); the meshes two at a time
    meshes = [j for j in todo if j[1][0] == "all"]
    states = [j for j in todo if j[1][0] in ("select", "deform")]
    adapts = [j for j in todo if j[1][0] == "adapt"]

    def run(job):
        name, args = job
        r = subprocess.run([exe(), *args], capture_output=True, text=True)
        if r.returncode != 0:
            raise SystemExit(
                f"{name}: deformesh {' '.join(args)} exited {r.returncode}: {r.stderr.strip()}"
            )

    with ThreadPoolExecutor(2) as pool:
        list(pool.map(run, meshes))
    for job in states:
        run(job)
    for name, args in adapts:  # (the sample's mesh, written above)
        run((name, [*args, "-o", str(out / name), "-q", "--monitor", ring(Path(args[1]))]))
    return {p.name: digest(p) for p in sorted(out.iterdir())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--write", type=Path, help="record the hashes in this JSON file")
    g.add_argument("--check", type=Path, help="compare with the hashes in this JSON file")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        got = run_all(Path(d))
    if a.write:
        a.write.write_text(json.dumps(got, indent=1, sort_keys=True) + "\n")
        print(f"{len(got)} files hashed -> {a.write}")
        return
    want = json.loads(a.check.read_text())
    bad = sorted(k for k in set(want) | set(got) if want.get(k) != got.get(k))
    for k in bad:
        print(f"differs: {k}: recorded {want.get(k, 'missing')}, now {got.get(k, 'missing')}")
    print(f"{len(got)} files, {len(bad)} differ from {a.check}")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
