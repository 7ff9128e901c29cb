"""Random hostile contours, reproducible from a seed: the kinds that break meshers.

Each maker takes a numpy Generator and a point count and returns ``(points, ring)``:
the points of one or more closed rings and, per point, its ring id (0 for a single
ring).  All of them are valid contours (simple rings, apart from each other); what
makes them hard is their shape: jagged angle-sorted point clouds, uneven stars,
points bunched in clusters, long thin spikes, combs of narrow slots, two parts a
hair apart, and holes close to the outline.  :func:`catalogue` lists ``count`` of
them, the kinds in turn, with point counts from 10 up to ``max_points``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import shapely

Maker = Callable[[np.random.Generator, int], tuple[np.ndarray, np.ndarray]]


def _one(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return p, np.zeros(len(p), dtype=np.int64)


def angle_sorted(rng: np.random.Generator, n: int):
    """Random points in a disk, walked in order of angle about the centre: jagged."""
    r = np.sqrt(rng.uniform(0.05, 1.0, n))
    t = np.sort(rng.uniform(0, 2 * np.pi, n))
    return _one(np.c_[r * np.cos(t), r * np.sin(t)])


def uneven_star(rng: np.random.Generator, n: int):
    """A star whose tips and valleys vary in depth and in angular spacing."""
    n += n % 2
    t = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = np.where(np.arange(n) % 2 == 0, rng.uniform(0.7, 1.0, n), rng.uniform(0.05, 0.6, n))
    return _one(np.c_[r * np.cos(t), r * np.sin(t)])


def clusters(rng: np.random.Generator, n: int):
    """A smooth blob whose points bunch in a few tight clusters of angle."""
    k = rng.integers(2, 6)
    centres = rng.uniform(0, 2 * np.pi, k)
    t = np.sort(np.concatenate([rng.normal(c, 0.02, n // (2 * k)) for c in centres]) % (2 * np.pi))
    t = np.unique(np.concatenate([t, np.linspace(0, 2 * np.pi, n - len(t), endpoint=False)]))
    r = 1 + 0.2 * np.sin(3 * t)
    return _one(np.c_[r * np.cos(t), r * np.sin(t)])


def spikes(rng: np.random.Generator, n: int):
    """A circle with a few long, thin spikes."""
    m = max(8, n - 3 * rng.integers(1, 5))
    t = np.linspace(0, 2 * np.pi, m, endpoint=False)
    p = [np.array([np.cos(a), np.sin(a)]) for a in t]
    out = []
    tips = set(rng.choice(m, size=min(m // 4, (n - m) // 3 + 1), replace=False).tolist())
    for i, q in enumerate(p):
        out.append(q)
        if i in tips:
            a = t[i] + np.pi / m
            w = rng.uniform(0.002, 0.02)
            length = rng.uniform(1.0, 3.0)
            d = np.array([np.cos(a), np.sin(a)])
            side = np.array([-d[1], d[0]])
            base = 0.98 * d
            out += [base - w * side, base + length * d, base + w * side]
    return _one(np.array(out))


def comb(rng: np.random.Generator, n: int):
    """A bar with narrow teeth: long slots a few thousandths wide."""
    teeth = max(2, (n - 4) // 4)
    width = 1.0 / teeth
    slot = rng.uniform(0.005, 0.3) * width
    depth = rng.uniform(0.5, 3.0)
    top = []
    for k in range(teeth):
        x0 = k * width
        top += [(x0, depth), (x0 + width - slot, depth), (x0 + width - slot, 0.0),
                (x0 + width, 0.0)]  # fmt: skip
    p = np.array([(0.0, -0.5), (1.0, -0.5), *top[::-1][:-1], (0.0, depth)])
    # (the last tooth's right side is the bar's right side: drop the duplicate corner)
    return _one(np.array([q for i, q in enumerate(p) if i == 0 or not np.allclose(q, p[i - 1])]))


def near_touching(rng: np.random.Generator, n: int):
    """Two blobs a hair apart (a gap of 1e-4 to 1e-2 of their size)."""
    m = max(5, n // 2)
    gap = 10 ** rng.uniform(-4, -2)
    t = np.linspace(0, 2 * np.pi, m, endpoint=False)
    a = np.c_[np.cos(t), np.sin(t)] * rng.uniform(0.5, 1.0, (m, 1))
    a[:, 0] -= a[:, 0].max() + gap / 2
    b = np.c_[np.cos(t), np.sin(t)] * rng.uniform(0.5, 1.0, (m, 1))
    b[:, 0] -= b[:, 0].min() - gap / 2
    return np.vstack([a, b]), np.repeat([0, 1], m)


def hole_near_outline(rng: np.random.Generator, n: int):
    """A jagged outline with a hole that comes within a hair of it."""
    m = max(6, 2 * n // 3)
    t = np.linspace(0, 2 * np.pi, m, endpoint=False)
    outer = np.c_[np.cos(t), np.sin(t)] * rng.uniform(0.8, 1.0, (m, 1))
    k = max(3, n - m)
    s = np.linspace(0, 2 * np.pi, k, endpoint=False)[::-1]
    r = rng.uniform(0.1, 0.4)
    reach = shapely.Polygon(outer).exterior.distance(shapely.Point(0, 0))
    centre = np.array([reach - r - 10 ** rng.uniform(-3, -1.5), 0.0])
    hole = centre + r * np.c_[np.cos(s), np.sin(s)]
    return np.vstack([outer, hole]), np.repeat([0, 1], [m, k])


KINDS: dict[str, Maker] = {
    "angle-sorted": angle_sorted,
    "uneven-star": uneven_star,
    "clusters": clusters,
    "spikes": spikes,
    "comb": comb,
    "near-touching": near_touching,
    "hole": hole_near_outline,
}


def valid(points: np.ndarray, ring: np.ndarray) -> bool:
    """Simple rings, apart from each other (what a contour must be)."""
    polys = [shapely.Polygon(points[ring == r]) for r in np.unique(ring)]
    if not all(p.is_valid and p.area > 0 for p in polys):
        return False
    rings = [p.exterior for p in polys]
    return all(not a.intersects(b) for i, a in enumerate(rings) for b in rings[i + 1 :])


def catalogue(count: int, max_points: int = 500, seed: int = 0):
    """``count`` valid random contours: ``(name, points, ring)``, the kinds in turn."""
    rng = np.random.default_rng(seed)
    names = list(KINDS)
    out = []
    while len(out) < count:
        kind = names[len(out) % len(names)]
        n = int(np.exp(rng.uniform(np.log(10), np.log(max_points))))
        p, r = KINDS[kind](rng, n)
        if valid(p, r):
            out.append((f"{len(out):03d}-{kind}-{len(p)}", p, r))
    return out


def write_csv(path, points: np.ndarray, ring: np.ndarray) -> None:
    """A contour CSV (``x,y`` or, with several rings, ``x,y,ring``)."""
    several = len(np.unique(ring)) > 1
    lines = ["x,y,ring" if several else "x,y"]
    for (x, y), k in zip(points, ring, strict=True):
        x, y = repr(float(x)), repr(float(y))  # (shortest text that reads back exactly)
        lines.append(f"{x},{y},{k}" if several else f"{x},{y}")
    path.write_text("\n".join(lines) + "\n")


def fingers(width: float, length: float, n: int = 5, gap: float = 1.0) -> np.ndarray:
    """A base 1 high with ``n`` fingers ``width`` wide and ``length`` long on it, ``gap``
    apart: thin parts of the domain (its points, counter-clockwise)."""
    right = n * width + (n + 1) * gap
    pts = [(0.0, 0.0), (right, 0.0), (right, 1.0)]
    x = right
    for _ in range(n):
        x -= gap
        pts += [(x, 1.0), (x, 1.0 + length)]
        x -= width
        pts += [(x, 1.0 + length), (x, 1.0)]
    pts.append((0.0, 1.0))
    return np.array(pts)
