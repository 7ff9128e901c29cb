"""``deformesh quality MESH [--contour CONTOUR]``: a mesh's measures and its contract."""

from __future__ import annotations

import click

from .. import files, formats, quality
from ..options import MeshOptions
from ..readers import load_contour
from .errors import fail, handle_errors
from .options import contour_reading, json_option, positive, quiet_option, take


@click.command("quality")
@click.argument("mesh_path", metavar="MESH", type=click.Path(dir_okay=False))
@click.option(
    "--contour",
    "contour_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Check the mesh contract against this contour (the file it was made from).",
)
@click.option(
    "--first-height",
    "first",
    type=float,
    callback=positive,
    default=None,
    metavar="H",
    help="Boundary layers: measure the quads' stacks (first heights, wall angles, "
    "growth) and count those whose first height is within 1% of H.",
)
@contour_reading()
@json_option("Print the report as JSON.")
@quiet_option
@handle_errors
def command(
    mesh_path: str, contour_path: str | None, first, as_json: bool, quiet: bool, **kwargs
) -> None:
    """Report a mesh's angles, areas and radius ratios; check the contract against a contour.

    A mesh with quads also gets their convexity, angles, scaled Jacobians, aspect
    ratios and share of the area; with --first-height (boundary layers), their
    stacks' first heights, wall angles and growth.  Exit 1 if a triangle is folded, a quad
    not convex, or (with --contour) the contract is broken; with -q, that is all it
    says.
    """
    o = take(MeshOptions, kwargs)
    points, tri, quads = formats.read_mesh(mesh_path, quads=True)
    c = None
    if contour_path is not None:
        c = load_contour(
            contour_path, None, o.decimal, o.tolerance, o.element_id, o.resample, o.stroke
        )
    rep, problem = quality.assess(points, tri, c, quads, first)
    rep = {"mesh": mesh_path, **rep}
    if not quiet:
        files.write_stdout(files.to_json(rep) if as_json else quality_text(rep))
    if problem:
        fail(f"{mesh_path}: {problem}")


def quality_text(r: dict) -> str:
    """The report as text: sizes, angles, areas, radius ratios and their histogram."""
    quads = f", {r['quads']} quads" if r.get("quads") else ""
    out = [
        f"{r['mesh']}: {r['nodes']} nodes, {r['triangles']} triangles{quads}, area {r['area']:.6g}"
    ]
    if r["triangles"]:
        out += _triangle_lines(r)
    if r.get("quads"):
        out += _quad_lines(r["quad_quality"], r.get("layers"))
    out.append(f"contract: {r['contract']}")
    return "\n".join(out)


def _quad_lines(q: dict, layers: dict | None) -> list[str]:
    """The quads' lines of the report (and their stacks', for boundary layers)."""
    out = [
        f"quads: {q['non_convex']} not convex; angles {q['min_angle']:.2f}-"
        f"{q['max_angle']:.2f} deg; scaled Jacobian min {q['min_scaled_jacobian']:.3f}; "
        f"aspect ratio mean {q['mean_aspect_ratio']:.3g}, max {q['max_aspect_ratio']:.3g}; "
        f"{100 * q['area_share']:.1f}% of the area",
    ]
    if layers and layers["stacks"]:
        out.append(
            f"layers: {layers['stacks']} stacks ({layers['fans']} fan points left out); first "
            f"height {layers['first_height_min']:.3g}-{layers['first_height_max']:.3g}; wall "
            f"angle min {layers['min_wall_angle']:.1f} deg"
            + (
                f"; growth {layers['growth_min']:.3g}-{layers['growth_max']:.3g}"
                if layers["growth_min"] is not None
                else ""
            )
        )
    if layers and "first_height_within_1pct" in layers:
        worst = 100 * layers["first_height_max_difference"]
        out.append(
            f"first height within 1% of H at {layers['first_height_within_1pct']} of "
            f"{layers['stacks']} stacks (largest difference {worst:.2f}%)"
        )
    return out


def _triangle_lines(r: dict) -> list[str]:
    """The triangles' lines of the report."""
    x, y = r["smallest_area_at"]
    out = [
        f"angles: min {r['min_angle']:.2f} deg, max {r['max_angle']:.2f} deg; "
        f"{r['angles_below_20']} triangle(s) with an angle below 20 deg",
        f"smallest signed area: {r['smallest_area']:.3g} at ({x:.6g}, {y:.6g}); "
        f"folded: {r['folded']}",
        f"radius ratio 2r/R: mean {r['mean_radius_ratio']:.3f}, min {r['min_radius_ratio']:.3f}",
    ]
    h = r["radius_ratio_histogram"]
    top = max(h["counts"]) or 1
    for lo, hi, k in zip(h["edges"], h["edges"][1:], h["counts"]):
        out.append(f"  {lo:.1f}-{hi:.1f} {k:9d} {'#' * round(40 * k / top)}".rstrip())
    return out
