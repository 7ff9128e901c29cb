"""Build tests/data/corpus/: real contours from public packages, as deformesh reads them.

    python scripts/make_corpus.py            # fetches the packages (npm pack, pip download)
    python scripts/make_corpus.py --from DIR # uses the archives already in DIR

Sources (versions pinned; licences in tests/data/corpus/SOURCES.md):
- airfoils: the UIUC coordinates that AeroSandbox 4.2.10 ships (PyPI, MIT), Selig or
  Lednicer .dat -> CSV x,y;
- icons: simple-icons 16.37.0 (npm, CC0) and bootstrap-icons 1.13.2 (npm, MIT), the SVG
  files as they are;
- coastlines: world-atlas 2.0.2 (npm, ISC; Natural Earth 1:50m, public domain), the
  largest polygon of some countries, TopoJSON arcs decoded -> CSV lon,lat.
Tests never download: they read what this script wrote.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "tests" / "data" / "corpus"

AIRFOILS = [
    "e387",
    "clarky",
    "naca2412",
    "s1223",
    "fx63137",
    "ag35",
    "mh32",
    "sd7037",
    "rae2822",
    "e423",
    "dae11",
    "ah79100a",
    "naca4412",
    "n0012",
    "usa35b",
    "hsnlf213",
    "sc20714",
    "lrn1015",
    "s8036",
    "goe398",
]
SIMPLE_ICONS = [
    "apple",
    "android",
    "github",
    "docker",
    "python",
    "rust",
    "nodedotjs",
    "debian",
    "ubuntu",
    "mozilla",
    "spotify",
    "x",
]
BOOTSTRAP = [
    "heart-fill",
    "star-fill",
    "cloud-fill",
    "house-fill",
    "bell-fill",
    "gear-fill",
    "bookmark-fill",
    "lightning-fill",
]
COUNTRIES = [
    "Australia",
    "Madagascar",
    "Iceland",
    "Sri Lanka",
    "Ireland",
    "Cuba",
    "Chile",
    "Norway",
    "Italy",
    "India",
]

PACKAGES = {
    "aerosandbox": ("pip", "aerosandbox==4.2.10"),
    "simple-icons": ("npm", "simple-icons@16.37.0"),
    "bootstrap-icons": ("npm", "bootstrap-icons@1.13.2"),
    "world-atlas": ("npm", "world-atlas@2.0.2"),
}


def fetch(where: Path) -> None:
    """npm pack / pip download every package into ``where`` (the only network use)."""
    for kind, spec in PACKAGES.values():
        if kind == "npm":
            subprocess.run(
                ["npm", "pack", spec, "--silent"], cwd=where, check=True, stdout=subprocess.DEVNULL
            )
        else:
            subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "pip",
                    "download",
                    spec,
                    "--no-deps",
                    "-q",
                    "-d",
                    str(where),
                ],
                check=True,
            )


def unpack(where: Path) -> dict[str, Path]:
    roots = {}
    for name in PACKAGES:
        if name == "aerosandbox":
            whl = next(where.glob("aerosandbox-*.whl"))
            d = where / "aerosandbox"
            zipfile.ZipFile(whl).extractall(d)
            roots[name] = d / "aerosandbox" / "geometry" / "airfoil" / "airfoil_database"
        else:
            tgz = next(where.glob(f"{name}-*.tgz"))
            d = where / name
            with tarfile.open(tgz) as t:
                t.extractall(d, filter="data")
            roots[name] = d / "package"
    return roots


def read_dat(path: Path) -> np.ndarray:
    """A UIUC .dat: a name line, then Selig (one loop) or Lednicer (counts, upper, lower)."""
    rows = []
    for line in path.read_text(errors="replace").splitlines()[1:]:
        parts = line.replace(",", " ").split()
        try:
            vals = [float(v) for v in parts[:2]]
        except ValueError:
            continue
        if len(vals) == 2:
            rows.append(vals)
    xy = np.array(rows)
    if len(xy) and xy[0, 0] > 1.5 and xy[0, 1] > 1.5:  # Lednicer: point counts first
        nu, nl = int(xy[0, 0]), int(xy[0, 1])
        upper, lower = xy[1 : 1 + nu], xy[1 + nu : 1 + nu + nl]
        xy = np.vstack([upper[::-1], lower[1:] if np.allclose(lower[0], upper[0]) else lower])
    return xy


def decode_topojson(topo: dict, arcs_of_ring) -> np.ndarray:
    sx, sy = topo["transform"]["scale"]
    tx, ty = topo["transform"]["translate"]
    pts = []
    for k in arcs_of_ring:
        arc = np.cumsum(np.array(topo["arcs"][k if k >= 0 else ~k], dtype=np.int64), axis=0)
        xy = arc * [sx, sy] + [tx, ty]
        if k < 0:
            xy = xy[::-1]
        pts.append(xy if not pts else xy[1:])
    return np.vstack(pts)


def ring_area(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))


def write_csv(path: Path, xy: np.ndarray, comment: str) -> None:
    with open(path, "w", newline="\n") as f:
        f.write(f"# {comment}\nx,y\n")
        for x, y in xy:
            f.write(f"{float(x)!r},{float(y)!r}\n")


def build(roots: dict[str, Path]) -> list[tuple[str, str, str]]:
    made = []
    OUT.mkdir(parents=True, exist_ok=True)
    for name in AIRFOILS:
        src = roots["aerosandbox"] / f"{name}.dat"
        xy = read_dat(src)
        write_csv(
            OUT / f"airfoil_{name}.csv",
            xy,
            f"{name} from the UIUC airfoil database as shipped by AeroSandbox 4.2.10",
        )
        made.append((f"airfoil_{name}.csv", "aerosandbox 4.2.10 (PyPI)", "MIT (UIUC data: free)"))
    for name in SIMPLE_ICONS:
        shutil.copy(roots["simple-icons"] / "icons" / f"{name}.svg", OUT / f"icon_si_{name}.svg")
        made.append((f"icon_si_{name}.svg", "simple-icons 16.37.0 (npm)", "CC0-1.0"))
    for name in BOOTSTRAP:
        shutil.copy(roots["bootstrap-icons"] / "icons" / f"{name}.svg", OUT / f"icon_bi_{name}.svg")
        made.append((f"icon_bi_{name}.svg", "bootstrap-icons 1.13.2 (npm)", "MIT"))
    topo = json.loads((roots["world-atlas"] / "countries-50m.json").read_text())
    by_name = {g["properties"]["name"]: g for g in topo["objects"]["countries"]["geometries"]}
    for name in COUNTRIES:
        g = by_name[name]
        polys = g["arcs"] if g["type"] == "MultiPolygon" else [g["arcs"]]
        rings = [decode_topojson(topo, poly[0]) for poly in polys]
        outer = max(rings, key=ring_area)
        slug = name.lower().replace(" ", "_")
        write_csv(
            OUT / f"coast_{slug}.csv",
            outer,
            f"{name}, largest polygon, Natural Earth 1:50m via world-atlas 2.0.2; lon,lat",
        )
        made.append(
            (
                f"coast_{slug}.csv",
                "world-atlas 2.0.2 (npm), Natural Earth",
                "ISC (package), public domain (data)",
            )
        )
    return made


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--from", dest="src", type=Path, help="folder holding the archives")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        where = Path(d)
        if args.src:
            for f in args.src.iterdir():
                if f.suffix in (".tgz", ".whl"):
                    shutil.copy(f, where)
        else:
            fetch(where)
        made = build(unpack(where))
    lines = [
        "# Corpus: real contours from public packages",
        "",
        "Written by `scripts/make_corpus.py` (it says how each file was converted). "
        "Coordinates as published; icons are the packages' SVG files unchanged.",
        "",
        "| file | from | licence |",
        "| --- | --- | --- |",
    ]
    lines += [f"| {f} | {src} | {lic} |" for f, src, lic in made]
    (OUT / "SOURCES.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {len(made)} contours to {OUT}", file=sys.stderr)


if __name__ == "__main__":
    main()
