"""``deformesh move MESH FRAME... --out-dir DIR``: a mesh carried along moving contours."""

from __future__ import annotations

import click

from .. import files, formats
from ..move import move_frames
from ..options import MoveOptions
from .errors import handle_errors
from .options import fields, force_option, json_option, quiet_option, say, take


@click.command("move")
@click.argument("mesh_path", metavar="MESH", type=click.Path(dir_okay=False))
@click.argument(
    "frames", metavar="FRAME...", nargs=-1, required=True, type=click.Path(dir_okay=False)
)
@click.option(
    "--out-dir",
    required=True,
    type=click.Path(file_okay=False),
    help="Write the frames here as NAME_0000.FORMAT, ... (created if missing), "
    "and NAME.pvd, the time series ParaView opens (.vtu only).",
)
@click.option("--name", default=None, help="File name stem.  Default: MESH's.")
@fields(MoveOptions, "dt", "steps", "solver", "solve", "fmt", "decimal", "min_angle", "remesh")
@force_option
@json_option()
@quiet_option
@handle_errors
def command(mesh_path, frames, out_dir, name, force, as_json, quiet, **kwargs) -> None:
    """Carry a mesh along as its contour moves: one file per FRAME, same triangles.

    MESH is a mesh deformesh wrote (its nodes 0..m-1 are the contour points in
    order); each FRAME is a contour of the same m points, point k following
    point k.  Each frame's mesh is the previous one deformed (the div-curl
    scheme over pseudo-time, contour nodes to the frame's points, box nodes
    held), checked for folds at every step.  Frame 0 is MESH itself.
    """
    o = take(MoveOptions, kwargs)

    def progress(k, count, contour, r):
        if r["remeshed"]:
            say(
                quiet,
                f"frame {k}/{count} {contour.source}: meshed afresh under the floor "
                f"(--min-angle), new triangles from here on: {r['triangles']} triangles, "
                f"min angle {r['min_angle']:.1f} deg",
            )
            return
        say(
            quiet,
            f"frame {k}/{count} {contour.source}: min angle {r['min_angle']:.1f} deg, "
            f"{r['solves']} solves, {r['halvings']} step halvings",
        )

    s = move_frames(mesh_path, list(frames), out_dir, o, name=name, force=force, on_frame=progress)
    if as_json:
        files.write_stdout(files.to_json(s))
    if s["format"] not in formats.POINT_DATA_FORMATS:
        say(quiet, f"note: .{s['format']} has no point data: the velocity is not written")
    say(
        quiet,
        f"{s['frames']} frames -> {out_dir}"
        f"{'/' + s['pvd'] if s['pvd'] else ''}: "
        + (
            f"same {s['triangles']} triangles"
            + (f" and {s['quads']} quads" if s["quads"] else "")
            + " in every frame"
            if not s["remeshed_frames"]
            else f"meshed afresh at frame(s) {', '.join(map(str, s['remeshed_frames']))}"
        )
        + f", min angle {s['min_angle']:.1f} deg over all frames (frame 0: "
        f"{s['min_angle_first']:.1f}) ({s['seconds']:.2f} s)",
    )
