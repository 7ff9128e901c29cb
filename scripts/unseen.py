"""Mesh real contours that are not in this repository, as a new user would meet them.

    python scripts/unseen.py --work /tmp/unseen            # icons and GeoJSON regions
    python scripts/unseen.py --work /tmp/unseen --only icons

Fetches public npm packages with ``npm pack`` into ``--work`` (nothing is committed:
world-geojson is GPL-3 data, the icon families carry their own licences), takes a
fixed sample of each (every Nth file in sorted order), meshes each sample as one
``deformesh all`` batch with ``--strict --json``, and prints, per family, how many
mesh and why the others are refused (grouped by the message's kind).  A development
tool for the claim "unseen inputs decide"; it needs the npm registry, so neither the
tests nor ``make bench`` run it.
"""

from __future__ import annotations

import argparse
import collections
import json
import re
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXE = Path(sys.executable).with_name("deformesh")

#: (family, npm package, folder inside the package, every Nth file, file filter)
ICONS = [
    ("bootstrap-icons", "bootstrap-icons@1.13.2", "icons", 10, None),
    ("fontawesome", "@fortawesome/fontawesome-free@7.3.1", "svgs", 30, None),
    ("heroicons-solid", "heroicons@2.2.0", ".", 5, "solid"),
    ("ionicons-filled", "ionicons@8.1.0", "dist/svg", 20, "-outline"),
    ("simple-icons", "simple-icons@16.37.0", "icons", 20, None),
    ("tabler-filled", "@tabler/icons@3.52.0", "icons/filled", 10, None),
]
REGIONS = ("world-geojson", "world-geojson@3.5.3")


def fetch(spec: str, work: Path) -> Path:
    """The unpacked npm package ``spec`` under ``work`` (fetched once)."""
    name = re.sub(r"[^A-Za-z0-9.-]+", "_", spec)
    out = work / name
    if not out.exists():
        got = subprocess.run(
            ["npm", "pack", spec, "--silent"], cwd=work, capture_output=True, text=True, check=True
        ).stdout.split()[-1]
        with tarfile.open(work / got) as tar:
            tar.extractall(out, filter="data")
    return out / "package"


def sample(pkg: Path, folder: str, every: int, filt: str | None, ext: str) -> list[Path]:
    files = sorted((pkg / folder).rglob(f"*{ext}"))
    files = [f for f in files if f.name != "package.json"]
    if filt and filt.startswith("-"):
        files = [f for f in files if filt[1:] not in f.name]
    elif filt:
        files = [f for f in files if filt in str(f.relative_to(pkg))]
    return files[every - 1 :: every]


def kind(error: str) -> str:
    for key, words in [
        ("pinched", "pinches to a point"),
        ("line icon (--stroke)", "--stroke"),
        ("self-intersecting", "intersects itself"),
        ("rings touch", "touches or crosses"),
        ("overlapping polygons", "overlap"),
        ("beyond the grid's range", "times smaller than the box"),
        ("hole outside", "hole"),
    ]:
        if words in error:
            return key
    return error.split(": ", 1)[-1][:80]


def run(family: str, files: list[Path], work: Path) -> None:
    batch = work / "batch" / family
    shutil.rmtree(batch, ignore_errors=True)
    batch.mkdir(parents=True)
    for k, f in enumerate(files):  # (names made unique: families repeat file names)
        shutil.copy(f, batch / f"{k:04d}_{f.name}")
    out = work / "meshes" / family
    r = subprocess.run(
        [str(EXE), "all", str(batch), "--out-dir", str(out), "--format", "vtk", "--strict",
         "--json", "-q", "-j", "2"],
        capture_output=True, text=True,
    )  # fmt: skip
    recs = [json.loads(line) for line in r.stdout.splitlines()]
    ok = [x for x in recs if x["status"] == "ok"]
    why = collections.Counter(kind(x.get("error", "")) for x in recs if x["status"] != "ok")
    slowest = max((x["seconds"] for x in recs), default=0.0)
    print(f"{family}: {len(ok)} of {len(recs)} mesh strict (slowest {slowest:.1f} s)")
    for what, n in why.most_common():
        print(f"    {n} refused: {what}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, required=True, help="folder for packages and meshes")
    ap.add_argument("--only", choices=["icons", "regions"])
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    if args.only != "regions":
        for family, spec, folder, every, filt in ICONS:
            run(family, sample(fetch(spec, args.work), folder, every, filt, ".svg"), args.work)
    if args.only != "icons":
        family, spec = REGIONS
        run(family, sample(fetch(spec, args.work), ".", 1, None, ".json"), args.work)


if __name__ == "__main__":
    main()
