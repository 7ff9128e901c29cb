"""Moving boundaries: ``deformesh move``, one connectivity for every frame."""

import json
import re
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from deformesh_cli import move, pipeline
from deformesh_cli.cli import cli
from deformesh_cli.contour import make_contour
from deformesh_cli.errors import DeformeshError, FoldError
from deformesh_cli.geometry import signed_areas
from deformesh_cli.quality import check_contract, measures
from deformesh_cli.readers import load_contour

from .conftest import SAMPLES, contour_file

PITCHING = sorted((SAMPLES / "pitching").glob("frame_*.csv"))
PULSATING = sorted((SAMPLES / "pulsating").glob("frame_*.csv"))


def _invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


def _sample(tmp_path_factory, name, contour, frames, *mesh_opts):
    d = tmp_path_factory.mktemp(name)
    r = _invoke("all", contour, "-o", d / f"{name}.vtu", "-q", *mesh_opts)
    assert r.exit_code == 0, r.stderr
    r = _invoke("move", d / f"{name}.vtu", *frames, "--out-dir", d / "frames", "--json")
    assert r.exit_code == 0, r.stderr
    return d, json.loads(r.stdout), r.stderr


@pytest.fixture(scope="module")
def pitching(tmp_path_factory):
    return _sample(
        tmp_path_factory,
        "pitching",
        SAMPLES / "pitching" / "naca0012_80.csv",
        PITCHING,
        "--exterior",
        "--box=-1.5,-1.5,2.5,1.5",
    )


@pytest.fixture(scope="module")
def pulsating(tmp_path_factory):
    return _sample(tmp_path_factory, "peanut", SAMPLES / "peanut.csv", PULSATING)


def _frames(d, summary):
    return [meshio.read(d / "frames" / r["output"]) for r in summary["per_frame"]]


@pytest.mark.parametrize("case", ["pitching", "pulsating"])
def test_every_frame_keeps_the_triangles_never_folds_and_sits_on_its_contour(case, request):
    d, summary, _ = request.getfixturevalue(case)
    frames = PITCHING if case == "pitching" else PULSATING
    files = _frames(d, summary)
    assert summary["frames"] == len(files) == len(frames) + 1
    first = files[0]
    tri0, line0 = first.cells_dict["triangle"], first.cells_dict["line"]
    reference = load_contour(frames[0])
    for k, m in enumerate(files):
        # the same index arrays in every frame
        assert np.array_equal(m.cells_dict["triangle"], tri0)
        assert np.array_equal(m.cells_dict["line"], line0)
        pts = m.points[:, :2]
        assert (signed_areas(pts, tri0) > 0).all()
        if k == 0:
            continue
        c = load_contour(frames[k - 1])
        assert np.array_equal(pts[: c.n], c.points)  # exactly, bit for bit
        assert c.n == reference.n
        # and the whole contract, against that frame's contour
        mesh, box = _mesh_for(pts, tri0, c)
        check_contract(mesh, c, box)
        # the velocity is the displacement from the frame before (dt = 1)
        v = m.point_data["velocity"]
        assert np.allclose(v[:, :2], pts - files[k - 1].points[:, :2], rtol=0, atol=1e-12)
        assert (v[:, 2] == 0).all()
    assert (files[0].point_data["velocity"] == 0).all()


def _mesh_for(pts, tri, c):
    from deformesh_cli.quality import mesh_for_contour

    return mesh_for_contour(pts, tri, c)


def test_pitching_min_angle_stays_within_5_degrees_of_the_first_frame(pitching):
    d, summary, err = pitching
    angles = [
        measures(m.points[:, :2], m.cells_dict["triangle"])[0].min() for m in _frames(d, summary)
    ]
    # reported as measured, over all frames
    assert summary["min_angle"] == pytest.approx(min(angles), abs=1e-9)
    assert summary["min_angle_first"] == pytest.approx(angles[0], abs=1e-9)
    assert summary["min_angle"] >= summary["min_angle_first"] - 5
    assert f"min angle {min(angles):.1f} deg over all frames" in err
    # the box does not move: its nodes are the same bits in every frame
    files = _frames(d, summary)
    x = files[0].points
    box = (
        (x[:, 0] == x[:, 0].min())
        | (x[:, 0] == x[:, 0].max())
        | (x[:, 1] == x[:, 1].min())
        | (x[:, 1] == x[:, 1].max())
    )
    assert box.sum() > 8
    for m in files[1:]:
        assert np.array_equal(m.points[box], x[box])


def test_pulsating_shape_keeps_its_angles(pulsating):
    d, summary, _ = pulsating
    assert summary["min_angle"] >= summary["min_angle_first"] - 5  # measured: 31.0 vs 35.1
    # the motion ends where it started: so does the mesh, near enough
    files = _frames(d, summary)
    assert np.abs(files[-1].points - files[0].points).max() < 1e-3


def test_the_pvd_lists_every_frame_in_time_order(pitching):
    d, summary, _ = pitching
    root = ET.parse(d / "frames" / summary["pvd"]).getroot()
    sets = root.find("Collection").findall("DataSet")
    assert [s.get("file") for s in sets] == [r["output"] for r in summary["per_frame"]]
    assert [float(s.get("timestep")) for s in sets] == list(range(len(sets)))
    for s in sets:
        assert (d / "frames" / s.get("file")).exists()


def test_extra_boundary_nodes_stay_on_their_edges(tmp_path):
    # NACA 0012 with 100 cosine-spaced points, exterior: 30 extra boundary nodes
    c = load_contour(contour_file("naca0012_100.csv"))
    res = pipeline.mesh_contour(
        c, exterior=True, box=(-1, -1, 2, 1), grid="uniform", merge_extra="keep"
    )
    m = res.mesh
    assert m.n_extra > 0
    motion = move.prepare(m.points, m.triangles, c, "mesh")
    a = np.radians(4)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    # turned, and squeezed a little (not rigid: the div-curl solve has work to do)
    frame = make_contour(((c.points - (0.25, 0)) @ rot.T) * (1, 0.9) + (0.25, 0), source="f")
    step = move.advance(motion, m.points, frame)
    assert step.stats.solves > 0
    # advance checks the contract (extra nodes on their edges, to 1e-12 of the size);
    # again here, by their parameter along the edge
    p = step.points
    ext = motion.moving[c.n :]
    t = motion.extra_at[:, None]
    want = (1 - t) * frame.points[motion.extra_from] + t * frame.points[motion.extra_to]
    assert np.allclose(p[ext], want, rtol=0, atol=1e-12)
    check_contract(move.frame_mesh(motion, p), frame, motion.box)


def test_each_ring_follows_its_own_rigid_motion():
    # a hole turning 10 degrees inside a square that stays put: the hole's turn is
    # carried from the hole (weight 1) to the square (weight 0)
    c = load_contour(contour_file("square_hole_100.csv"))
    m = pipeline.mesh_contour(c).mesh
    motion = move.prepare(m.points, m.triangles, c, "mesh")
    assert len(motion.rings) == 2
    for k, r in enumerate(motion.rings):  # 1 on its ring, 0 on the other, to the bit
        assert (motion.weights[k][motion.moving[r]] == 1).all()
        other = motion.moving[motion.rings[1 - k]]
        assert (motion.weights[k][other] == 0).all()
    hole = np.arange(c.starts[1], c.starts[2])
    first = measures(m.points, m.triangles)[0].min()
    pts = m.points
    for deg in (5, 10):
        a = np.radians(deg)
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        p = c.points.copy()
        centre = c.points[hole].mean(axis=0)
        p[hole] = (c.points[hole] - centre) @ rot.T + centre
        frame = make_contour(p, source=f"turned {deg}", ring_starts=c.starts[:-1])
        step = move.advance(motion, pts, frame)
        assert step.report["rigid_turn"][1] == pytest.approx(5)  # the hole, this frame
        assert step.report["rigid_turn"][0] == 0  # the square stays
        pts = step.points
        check_contract(move.frame_mesh(motion, pts), frame, motion.box)
    assert np.array_equal(pts[: c.starts[1]], c.points[: c.starts[1]])
    # measured 35.1 -> 29.4 (graded grid; one step for the whole domain: 35.4 -> 32.3)
    assert measures(pts, m.triangles)[0].min() >= first - 7


def test_rigid_fit_and_carry():
    rng = np.random.default_rng(1)
    p = rng.normal(size=(30, 2))
    a = 0.3
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    q = (p - p.mean(axis=0)) @ rot.T + (2.0, -1.0)
    cp, cq, theta = move.rigid_fit(p, q)
    assert theta == pytest.approx(a)
    w = np.ones(len(p))
    assert np.allclose(move.carry(p, w, cp, cq, theta), q)
    w[:10] = 0  # weight 0: not a bit moves
    out = move.carry(p, w, cp, cq, theta)
    assert np.array_equal(out[:10], p[:10])


def test_a_frame_that_would_fold_stops_with_the_frames_before_written(tmp_path):
    d = tmp_path
    # on one step for the whole domain (the graded grid's larger cells follow this frame)
    r = _invoke("all", SAMPLES / "peanut.csv", "-o", d / "m.vtu", "-q", "--grid", "uniform")
    assert r.exit_code == 0
    c = load_contour(SAMPLES / "peanut.csv")
    good = d / "f1.csv"
    np.savetxt(good, c.points * 1.02, delimiter=",", header="x,y", comments="")
    # frame 2: one point pulled deep inside (still a simple polygon), which the mesh
    # cannot follow without folding the triangles at its neighbours
    bad = c.points * 1.02
    k = 30
    bad[k] = bad[k] * 0.05
    np.savetxt(d / "f2.csv", bad, delimiter=",", header="x,y", comments="")
    r = _invoke("move", d / "m.vtu", good, d / "f2.csv", "--out-dir", d / "out")
    assert r.exit_code == 1
    assert "f2.csv: frame 2 of 2 cannot be reached without folding" in r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) <= 2
    written = sorted(p.name for p in (d / "out").iterdir())
    assert written == ["m.pvd", "m_0000.vtu", "m_0001.vtu"]


def test_bad_frames_are_refused_before_any_work(tmp_path):
    d = tmp_path
    assert _invoke("all", SAMPLES / "peanut.csv", "-o", d / "m.vtu", "-q").exit_code == 0
    c = load_contour(SAMPLES / "peanut.csv")
    np.savetxt(d / "ok.csv", c.points, delimiter=",", header="x,y", comments="")
    np.savetxt(d / "short.csv", c.points[:-1], delimiter=",", header="x,y", comments="")
    np.savetxt(d / "turned.csv", c.points[::-1], delimiter=",", header="x,y", comments="")
    for name, text in (
        ("short.csv", "has 119 points, the mesh's contour has 120"),
        ("turned.csv", "runs the other way round"),
    ):
        r = _invoke("move", d / "m.vtu", d / "ok.csv", d / name, "--out-dir", d / "out")
        assert r.exit_code == 1, r.stderr
        assert name in r.stderr and text in r.stderr
        assert not (d / "out").exists()  # nothing written, not even the folder
    # a mesh that is not deformesh's for these points
    np.savetxt(
        d / "other.csv",
        load_contour(SAMPLES / "circle.csv").points,
        delimiter=",",
        header="x,y",
        comments="",
    )
    r = _invoke("move", d / "m.vtu", d / "other.csv", "--out-dir", d / "out")
    assert r.exit_code == 1 and "m.vtu" in r.stderr
    # a first frame of another count: the frame is blamed, the mesh's count said
    np.savetxt(d / "f80.csv", c.points[::3][:80], delimiter=",", header="x,y", comments="")
    r = _invoke("move", d / "m.vtu", d / "f80.csv", "--out-dir", d / "out")
    assert r.exit_code == 1
    assert "f80.csv: has 40 points, but " in r.stderr and "m.vtu's contour has 120" in r.stderr
    # usage errors: exit 2
    assert _invoke("move", d / "m.vtu", d / "ok.csv").exit_code == 2  # no --out-dir
    assert _invoke("move", d / "m.vtu", "--out-dir", d / "out").exit_code == 2  # no frame
    assert (
        _invoke("move", d / "m.vtu", d / "ok.csv", "--out-dir", d / "o", "--dt", "0").exit_code == 2
    )


@st.composite
def motions(draw):
    """A star polygon and a few frames: turned, shifted and reshaped a little each."""
    n = draw(st.integers(8, 30))
    gaps = np.array(draw(st.lists(st.floats(0.4, 1.0), min_size=n, max_size=n)))
    theta = 2 * np.pi * np.cumsum(gaps) / gaps.sum()
    r = np.array(draw(st.lists(st.floats(0.6, 1.0), min_size=n, max_size=n)))
    steps = draw(
        st.lists(
            st.tuples(st.floats(-0.2, 0.2), st.floats(-0.1, 0.1), st.floats(-0.05, 0.05)),
            min_size=1,
            max_size=4,
        )
    )
    frames, angle, shift, bulge = [], 0.0, 0.0, np.zeros(n)
    for a, s, b in steps:
        angle, shift = angle + a, shift + s
        bulge = bulge + b * np.cos(3 * theta)
        rr = r * (1 + bulge)
        frames.append(
            np.column_stack([rr * np.cos(theta + angle) + shift, rr * np.sin(theta + angle)])
        )
    return np.column_stack([r * np.cos(theta), r * np.sin(theta)]), frames


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(motions(), st.booleans())
def test_random_motions_keep_the_contract_or_say_which_frame_folds(case, exterior):
    base, frames = case
    c = make_contour(base, source="base")
    # (a valid contour: the graded grid meshes it)
    res = pipeline.mesh_contour(c, exterior=exterior, box=(-3, -3, 3, 3) if exterior else None)
    m = res.mesh
    motion = move.prepare(m.points, m.triangles, c, "mesh")
    pts = m.points
    for k, f in enumerate(frames):
        try:
            frame = make_contour(f, source=f"frame {k}")
        except DeformeshError:
            return  # the random reshaping made an invalid polygon: refused as input
        try:
            step = move.advance(motion, pts, frame)
        except FoldError:
            return  # said plainly (the CLI names the frame)
        pts = step.points
        assert np.array_equal(pts[: c.n], frame.points)
        assert (signed_areas(pts, m.triangles) > 0).all()
        check_contract(move.frame_mesh(motion, pts), frame, motion.box)


def _body_in_a_box(folder):
    """An ellipse in a far-field box, shifted by 0.08 and turned 9 degrees a frame for 10
    frames: its smallest angle falls frame after frame (below 1 degree by frame 6)."""
    t = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    p = np.column_stack([0.3 * np.cos(t), 0.12 * np.sin(t)])
    np.savetxt(folder / "body.csv", p, delimiter=",")
    frames = []
    for k in range(1, 11):
        a = np.radians(9 * k)
        turn = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        frames.append(folder / f"frame_{k:02d}.csv")
        np.savetxt(frames[-1], p @ turn.T + [0.08 * k, 0.0], delimiter=",")
    r = _invoke("all", folder / "body.csv", "--exterior", "--box=-1,-1,2,1", "-o",
                folder / "body.vtu", "-q")  # fmt: skip
    assert r.exit_code == 0, r.stderr
    return folder / "body.vtu", frames


def test_a_frame_under_the_angle_floor_stops_the_run_with_the_frames_before_kept(tmp_path):
    mesh, frames = _body_in_a_box(tmp_path)
    out = tmp_path / "out"
    r = _invoke("move", mesh, *frames, "--out-dir", out)
    assert r.exit_code == 1
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith(f"deformesh: error: {frames[5]}: frame 6 of 10: its smallest angle ")
    assert "under the floor 2 (--min-angle); frames 0-5 are in" in last
    # each frame's line gives its smallest angle, every one above the floor
    angles = [float(x) for x in re.findall(r"min angle ([\d.]+) deg", r.stderr)]
    assert len(angles) == 5 and min(angles) >= 2.0
    assert sorted(p.name for p in out.glob("*.vtu")) == [f"body_{k:04d}.vtu" for k in range(6)]
    # no floor: the run goes on to the end, down to a fraction of a degree
    r = _invoke("move", mesh, *frames, "--out-dir", tmp_path / "all", "--min-angle", "0",
                "--json")  # fmt: skip
    assert r.exit_code == 0
    assert json.loads(r.stdout)["min_angle"] < 1.0


def test_remesh_meshes_a_frame_afresh_and_carries_the_velocity(tmp_path):
    mesh, frames = _body_in_a_box(tmp_path)
    out = tmp_path / "out"
    r = _invoke("move", mesh, *frames, "--out-dir", out, "--remesh", "--json")
    assert r.exit_code == 0, r.stderr
    s = json.loads(r.stdout)
    assert s["frames"] == 11 and s["remeshed_frames"] and s["min_angle"] >= 2.0
    assert all(f["min_angle"] >= 2.0 for f in s["per_frame"])
    assert "meshed afresh under the floor" in r.stderr
    k = s["remeshed_frames"][0]
    before = meshio.read(out / f"body_{k - 1:04d}.vtu")
    after = meshio.read(out / f"body_{k:04d}.vtu")
    assert len(after.cells_dict["triangle"]) != len(before.cells_dict["triangle"])
    # the velocity carried over: the body's nodes move with it, the box's stay
    v = after.point_data["velocity"]
    frame = np.loadtxt(frames[k - 1], delimiter=",")
    previous = np.loadtxt(frames[k - 2], delimiter=",")
    assert np.allclose(v[: len(frame), :2], frame - previous)
    box = (np.abs(after.points[:, 0] - 0.5) == 1.5) | (np.abs(after.points[:, 1]) == 1.0)
    assert np.abs(v[box]).max() == 0.0
    assert np.isfinite(v).all() and np.abs(v[len(frame) :]).max() > 0.0
    # every frame after it keeps the new triangles, and the contract on its own contour
    for j in range(k, 11):
        m = meshio.read(out / f"body_{j:04d}.vtu")
        assert np.array_equal(m.cells_dict["triangle"], after.cells_dict["triangle"])
        assert (signed_areas(m.points[:, :2], m.cells_dict["triangle"]) > 0).all()
