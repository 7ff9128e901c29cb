"""The README and docs/ are true: every command in their sh blocks runs, every Python
block runs, every option and --json key is documented, the README stays short."""

import json
import os
import re

import pytest

from .conftest import ROOT, SAMPLES

README = (ROOT / "README.md").read_text()
DOCS = {p.name: p.read_text() for p in sorted((ROOT / "docs").glob("*.md"))}
ALL_TEXT = README + "".join(DOCS.values())
PAGES = {"README.md": README, **{f"docs/{k}": v for k, v in DOCS.items()}}


def _blocks(kind):
    return [
        (name, b)
        for name, text in PAGES.items()
        for b in re.findall(rf"```{kind}\n(.*?)```", text, re.S)
    ]


COMMANDS = [
    (name, ln.split("  #")[0].strip())
    for name, b in _blocks("sh")
    for ln in b.splitlines()
    if ln.startswith("deformesh ")
]
SCRIPT_BLOCKS = [(name, b) for name, b in _blocks("sh") if "python scripts/" in b]


def test_readme_has_exactly_the_two_setup_commands():
    setup = [
        ln.split("#")[0].strip()
        for b in re.findall(r"```sh\n(.*?)```", README, flags=re.S)
        for ln in b.splitlines()
        if ln.startswith("make ")
    ]
    assert setup == ["make demo", "make test"]
    assert all("make " not in b for name, b in _blocks("sh") if name != "README.md")


def test_readme_is_short_and_links_every_docs_page():
    assert README.count("\n") <= 150
    for name in DOCS:
        assert f"(docs/{name})" in README, f"README does not link docs/{name}"


def test_docs_links_point_at_existing_pages_and_headings():
    for page, text in PAGES.items():
        for target, anchor in re.findall(r"\]\(((?:docs/)?[\w.]+\.md)(?:#([\w-]+))?\)", text):
            here = (ROOT / page).parent
            path = (here / target) if not target.startswith("docs/") else ROOT / target
            assert path.exists(), f"{page} links {target}"
            if anchor:
                heads = re.findall(r"^#+ (.*)$", path.read_text(), re.M)
                slugs = {
                    re.sub(r"[^\w\- ]", "", h).strip().lower().replace(" ", "-") for h in heads
                }
                assert anchor in slugs, f"{page} links {target}#{anchor}"


@pytest.mark.parametrize(
    "cmd", [c for _, c in COMMANDS], ids=[f"{n}: {c[:60]}" for n, c in COMMANDS]
)
def test_documented_command_runs(sh, tmp_path, cmd):
    os.symlink(ROOT / "samples", tmp_path / "samples")
    os.symlink(ROOT / "tests", tmp_path / "tests")
    (tmp_path / "out").mkdir()
    r = sh(cmd, cwd=tmp_path)
    assert r.returncode == 0
    assert list((tmp_path / "out").iterdir())


@pytest.mark.parametrize("block", [b for _, b in _blocks("python")], ids=lambda b: b[:40])
def test_documented_python_runs(tmp_path, block, monkeypatch):
    os.symlink(ROOT / "samples", tmp_path / "samples")
    (tmp_path / "out").mkdir()
    monkeypatch.chdir(tmp_path)
    exec(compile(block, "<docs>", "exec"), {})
    assert list((tmp_path / "out").iterdir())


def test_every_option_is_documented():
    from deformesh_cli.cli import cli

    for name, cmd in cli.commands.items():
        assert f"deformesh {name}" in README, f"README does not show deformesh {name}"
        assert f"deformesh {name}" in DOCS["commands.md"]
        for p in cmd.params:
            for opt in p.opts + getattr(p, "secondary_opts", []):
                if opt.startswith("--") and opt != "--help":
                    assert opt in DOCS["commands.md"] + DOCS["method.md"], (
                        f"{name} {opt} missing from docs/commands.md"
                    )


def test_every_json_key_is_documented(run, tmp_path):
    r = run("all", SAMPLES / "circle.csv", "-o", tmp_path / "m.vtk", "--json", "-q")
    assert r.exit_code == 0, r.stderr
    for key in json.loads(r.stdout):
        assert f"`{key}`" in DOCS["commands.md"], f"--json key {key} missing from docs/commands.md"


@pytest.mark.parametrize("block", [b for _, b in SCRIPT_BLOCKS], ids=lambda b: b[:40])
def test_blocks_with_scripts_run_in_order(sh, tmp_path, block):
    # a script line uses what the lines before it wrote: run the block as a whole
    for name in ("samples", "scripts"):
        os.symlink(ROOT / name, tmp_path / name)
    (tmp_path / "out").mkdir()
    (tmp_path / "docs").mkdir()
    sh("set -e\n" + block, cwd=tmp_path)
    assert list((tmp_path / "docs").iterdir())  # the picture the page shows


def test_nothing_cites_a_design_file_the_repository_does_not_have():
    """Docs and code cite what a clone has: no DESIGN.md, no planning notes."""
    assert not (ROOT / "DESIGN.md").exists()
    sources = [*ROOT.joinpath("deformesh_cli").rglob("*.py"), ROOT / "README.md"]
    sources += list(ROOT.joinpath("docs").glob("*.md"))
    cited = [p.name for p in sources if "DESIGN.md" in p.read_text()]
    assert cited == []


def test_no_history_in_the_docs():
    """Docs say what things do; history lives in CHANGELOG.md and the commit log."""
    for page, text in PAGES.items():
        assert not re.search(r"issue ?[0-9]", text, re.I), page
        assert "/".join(["..", "shared"]) not in text, page  # the workplace's folder


def test_limits_circle_numbers_are_the_benchmark_file():
    """docs/limits.md's circle times and memory are the rows ``make bench`` last wrote."""
    results = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    circles = results.split("<!-- section:circles -->")[1].split("<!-- end:circles -->")[0]
    rows = [
        [c.strip() for c in row.strip().strip("|").split("|")]
        for row in circles.splitlines()
        if re.match(r"\| [\d,]+ \|", row)
    ]
    said = re.search(
        r"take ([\d.]+), ([\d.]+) and ([\d.]+) s and (\d+), (\d+)\s+and (\d+) MB .*?"
        r"Triangle `pq30Y`'s ([\d.]+), ([\d.]+) and\s+([\d.]+) s",
        DOCS["limits.md"],
        re.S,
    )
    assert said is not None and len(rows) == 3
    ours = [r[1] for r in rows] + [r[2] for r in rows] + [r[5] for r in rows]
    assert list(said.groups()) == ours


def test_readme_speed_numbers_are_the_benchmark_files():
    """The README's "How fast" claims are the numbers ``make bench`` last wrote."""
    results = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    corpus = results.split("<!-- section:corpus -->")[1].split("<!-- end:corpus -->")[0]
    contours, wall = re.search(r"(\d+) contours in (\d+) s wall", corpus).groups()
    meshed = re.search(r"\| all \| \d+ \| (\d+) \(", corpus).group(1)
    claim = re.search(r"(\d+) of (\d+) real contours .*? in (\d+) s as one batch", README, re.S)
    assert claim is not None
    assert claim.groups() == (meshed, contours, wall)
    slowest = re.search(r"\| all \| \d+ \| \d+ \(\d+%\) \| \d+ \| [\d.]+ \| ([\d.]+) \|", corpus)
    said = re.search(r"as one batch \(none over (\d+\.\d) s\)", README)
    assert said is not None and float(said.group(1)) == round(float(slowest.group(1)), 1)
    ratio = re.search(r"triangles ([\d.]+) times Triangle's at the median", corpus).group(1)
    assert f"with {ratio} times Triangle `pq30Y`'s triangles at the median" in " ".join(
        README.split()
    )
    # the time ratios of the million-triangle runs ("Speed against peers")
    peers = results.split("<!-- section:peers-triangle -->")[1].split("<!-- end:")[0]
    ratio = {}
    for row in peers.splitlines():
        cells = [c.strip() for c in row.strip("|").split("|")]
        if len(cells) == 12 and cells[3] == "deformesh" and int(cells[4]) > 900_000:
            ratio[cells[0]] = cells[10]
    said = re.search(
        r"(\d\.\d\d) times\s+Triangle's time on a circle and (\d\.\d\d) on a bean\s+"
        r"\(NACA 0012: (\d\.\d\d)\)",
        README,
    )
    assert said is not None
    assert said.groups() == (ratio["circle"], ratio["bean"], ratio["naca0012"])
    # one process per corpus contour against a Triangle process ("corpus-processes")
    procs = results.split("<!-- section:corpus-processes -->")[1].split("<!-- end:")[0]
    median, largest = re.search(
        r"Our time over Triangle's: median ([\d.]+), largest ([\d.]+)", procs
    ).groups()
    said = re.search(
        r"one process per real contour takes a median ([\d.]+) times a Triangle "
        r"process's time \(up to ([\d.]+) on",
        " ".join(README.split()),
    )
    assert said is not None
    assert said.groups() == (median, str(round(float(largest), 1)))


def test_limits_corpus_numbers_are_the_benchmark_file():
    """docs/limits.md's corpus claims (batch time, the comparison with Triangle, the
    slowest contour) are the numbers ``make bench`` last wrote in RESULTS.md."""
    results = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    corpus = results.split("<!-- section:corpus -->")[1].split("<!-- end:corpus -->")[0]
    wall = re.search(r"contours in (\d+) s wall", corpus).group(1)
    meshed, wins, ratio, clean, fast = re.search(
        r"of the (\d+) meshed: smallest angle at least Triangle's on (\d+) \(\d+%\); "
        r"triangles ([\d.]+) times Triangle's at the median; (\d+) with no extra boundary "
        r"node; (\d+) under 1 s",
        corpus,
    ).groups()
    slowest = re.search(r"\| all \| \d+ \| \d+ \(\d+%\) \| \d+ \| [\d.]+ \| ([\d.]+) \|", corpus)
    text = " ".join(DOCS["limits.md"].split())
    assert f"in {wall} s for the whole batch" in text
    assert (
        f"{wins} of the {meshed} have a smallest angle at least Triangle's, with {ratio} "
        f"times its triangles at the median; {clean} have no extra boundary node"
    ) in text
    assert (
        f"at most {slowest.group(1)} s" in text and f"{fast} of the {meshed} take under 1 s" in text
    )


def test_limits_random_set_numbers_are_the_benchmark_file():
    """docs/limits.md's random-set claims (how many under 1 s, the slowest, the most
    extra boundary nodes) are the numbers ``make bench`` last wrote in RESULTS.md."""
    results = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    part = results.split("<!-- section:construct -->")[1].split("<!-- end:construct -->")[0]
    count = re.search(r"the first (\d+) polygons", part).group(1)
    slowest, fast, most = re.search(
        r"slowest ([\d.]+) s, (\d+) under 1 s; extra boundary nodes taken out: median \d+, "
        r"most (\d+)",
        part,
    ).groups()
    text = " ".join(DOCS["limits.md"].split())
    assert (
        f'of the {count} random polygons (`benchmarks/RESULTS.md`, "construct") {fast} take '
        f"under 1 s in process and the slowest {round(float(slowest))} s; one had "
        f"{int(most):,} extra boundary nodes"
    ) in text


def test_moving_numbers_in_the_docs_are_the_benchmark_file():
    """docs/commands.md's and docs/limits.md's numbers for ``move`` are the rows
    ``make bench`` last wrote in RESULTS.md ("Moving meshes")."""
    results = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    moving = results.split("<!-- section:moving -->")[1].split("<!-- end:moving -->")[0]
    rows = {}
    for row in moving.splitlines():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) == 12 and cells[1].isdigit():
            rows[cells[0]] = cells
    pitch, peanut = rows["pitching sample (README)"], rows["pulsating peanut (README)"]
    naca = rows["pitching NACA 0012, 160 points, box -2..3"]
    shape = rows["pulsating NACA 0012 (amplitude 0.1), whole mesh, --min-angle 0"]
    band = rows["pulsating NACA 0012 (amplitude 0.1), --solve band, --min-angle 0"]
    free = rows["ellipse in a box, 0.08 and 9 degrees a frame, --min-angle 0"]
    again = rows["ellipse in a box, 0.08 and 9 degrees a frame, --remesh"]
    commands = " ".join(DOCS["commands.md"].split())
    limits = " ".join(DOCS["limits.md"].split())

    def count(n: str) -> str:
        return f"{int(n):,}"

    assert f"({count(pitch[1])} triangles, {pitch[3]} s)" in commands
    assert f"{count(peanut[1])} triangles, {peanut[3]} s)" in commands
    assert f"{pitch[6]} degrees at frame 0 and {pitch[7]} at its lowest" in commands
    assert f"the peanut goes from {peanut[6]} to {peanut[7]} degrees" in commands
    assert (
        f"far field of {count(shape[1])} triangles reshaped by up to 15% ends at {shape[7]} "
        f"degrees on the whole mesh and at {band[7]} with the band"
    ) in commands
    assert f"{count(naca[1])} triangles: {naca[6]} degrees at frame 0, {naca[7]} at the" in limits
    assert f"(the beating peanut: {peanut[6]} to {peanut[7]}" in limits
    assert f"goes to {shape[7]} degrees on the whole mesh" in limits
    hole = rows["square_hole_100, the hole turning 10 degrees"]
    assert f"`square_hole_100`: {hole[6]} to {hole[7]})" in limits
    # the floor: the ellipse's frames, one by one, without it and with --remesh
    angles = {
        line.split(": ")[0][2:]: line.split(": ")[1].split()
        for line in moving.splitlines()
        if line.startswith("- ellipse")
    }
    without = angles[free[0]]
    assert f"down to {without[-1]} degrees at frame {len(without) - 1}" in commands
    assert f"`{' '.join(without)}`" in commands
    assert f"`{' '.join(angles[again[0]])}`" in commands
    assert f"meshed afresh at frame {again[11]}" in commands


def test_adapt_numbers_in_the_docs_are_the_benchmark_file():
    """README's, docs/commands.md's and docs/limits.md's numbers for ``adapt`` are the
    rows ``make bench`` last wrote in RESULTS.md ("adapt")."""
    results = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    part = results.split("<!-- section:adapt -->")[1].split("<!-- end:adapt -->")[0]
    rows = {}
    for row in part.splitlines():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) == 11 and cells[1].isdigit():
            rows[(cells[0], cells[2])] = cells[:3] + cells[4:] + cells[3:4]  # solves last
        if len(cells) == 7 and cells[0] in ("gradient", "hessian"):
            rows[(cells[0], cells[1])] = cells
    ring = rows[("movement's ring, 20 x 20", "defaults")]
    more = rows[("movement's ring, 20 x 20", "--steps 80")]
    wake = next(v for k, v in rows.items() if k[0].startswith("samples/naca0012.csv"))
    big = next(v for k, v in rows.items() if k[0] == "ring, 300 x 300")
    grad, hess = rows[("gradient", "10")], rows[("hessian", "10")]
    commands = " ".join(DOCS["commands.md"].split())
    limits = " ".join(DOCS["limits.md"].split())
    readme = " ".join(README.split())
    assert (
        f"sigma/mu goes from {ring[3]} to {ring[4]} and the volume ratio from {ring[5]} to "
        f"{ring[6]}, where `movement`'s converged Monge-Ampere mesh has 0.348 and 8.84"
    ) in commands
    assert f"error in L2 to {grad[4]} of what it was, `--kind hessian` to {hess[4]}" in commands
    assert (
        f"sigma/mu {ring[3]} to {ring[4]} and volume ratio {ring[5]} to {ring[6]}, where"
    ) in readme
    assert f"the equidistribution measures reach {ring[4]} and {ring[6]}," in limits
    assert float(more[4]) < float(ring[4])  # (more solves: closer still)
    assert (
        f"leaves sigma/mu at {wake[4]} from {wake[3]} and the volume ratio at {wake[6]} from "
        f"{wake[5]}"
    ) in limits
    assert (
        f"(180,000 triangles) takes {big[8]} s as a whole process, {big[9]} MB ({big[10]} solves)"
    ) in limits
    profile = {
        cells[0]: cells
        for cells in (
            [c.strip() for c in row.strip().strip("|").split("|")] for row in part.splitlines()
        )
        if len(cells) == 4 and cells[0] in ("20 x 20", "40 x 40", "71 x 71")
    }
    assert (
        f"falls from {profile['20 x 20'][1]} to {profile['20 x 20'][2]}, on 40 x 40 squares "
        f"from {profile['40 x 40'][1]} to {profile['40 x 40'][2]}, on 71 x 71 from "
        f"{profile['71 x 71'][1]} to {profile['71 x 71'][2]}"
    ) in limits


@pytest.mark.parametrize("shell", ["bash", "zsh", "fish"])
def test_shell_completion_is_documented_and_works(sh, shell):
    line = 'eval "$(_DEFORMESH_COMPLETE=bash_source deformesh)"'
    assert line in DOCS["commands.md"]
    assert f"`{shell}_source`" in DOCS["commands.md"] or shell == "bash"
    script = sh(f"_DEFORMESH_COMPLETE={shell}_source deformesh").stdout.decode()
    assert "_DEFORMESH_COMPLETE" in script and len(script) > 200
    if shell == "bash":  # the completion offers the subcommands
        got = sh(
            "COMP_WORDS='deformesh mo' COMP_CWORD=1 _DEFORMESH_COMPLETE=bash_complete deformesh"
        ).stdout.decode()
        assert "move" in got


def test_limits_peer_numbers_are_the_benchmark_file():
    """docs/limits.md's comparison with Triangle (the million-triangle rows: seconds,
    time and memory ratios, triangles per second; the smaller rows' ranges) and the
    coastlines' process ratios are the rows ``make bench`` last wrote."""
    results = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    text = " ".join(DOCS["limits.md"].split())
    peers = results.split("<!-- section:peers-triangle -->")[1].split("<!-- end:")[0]
    rows = [
        [c.strip() for c in row.strip("|").split("|")]
        for row in peers.splitlines()
        if row.startswith("| ") and len(row.strip("|").split("|")) == 12
    ]
    rows = [r for r in rows if r[3] in ("deformesh", "triangle")]
    big = {(r[0], r[3]): r for r in rows if int(r[4]) > 900_000}
    ours = {s: big[(s, "deformesh")] for s in ("circle", "bean", "naca0012")}
    assert (
        f"deformesh takes {ours['circle'][5]} s on the circle and {ours['bean'][5]} s on the "
        f"bean, {ours['circle'][10]} and {ours['bean'][10]} times Triangle's time in the same "
        f"run (NACA 0012: {ours['naca0012'][10]}), with peak RSS "
        f"{min(float(r[11]) for r in ours.values()):.1f} to "
        f"{max(float(r[11]) for r in ours.values()):.1f} times Triangle's"
    ) in text

    def rate(tool):
        v = [float(r[6].replace(",", "")) / 1e6 for (_, t), r in big.items() if t == tool]
        return f"{min(v):.2f}e6 to {max(v):.2f}e6"

    assert f"({rate('triangle')} against {rate('deformesh')} triangles per second)" in text
    small = [r for r in rows if r[3] == "deformesh" and int(r[4]) < 900_000]
    seconds = [float(r[5]) for r in small]
    ratios = [float(r[10]) for r in small]
    assert (
        f"Up to 1e5 triangles deformesh takes {min(seconds):.2f} to {max(seconds):.2f} s, "
        f"{min(ratios):.2f} to {max(ratios):.2f} times Triangle's"
    ) in text
    procs = results.split("<!-- section:corpus-processes -->")[1].split("<!-- end:")[0]
    coast = [
        float(r) for r in re.findall(r"\| coast_\w+\.csv \| [\d.]+ \| [\d.]+ \| ([\d.]+) \|", procs)
    ]
    top = sorted(coast, reverse=True)[:4]
    assert f"the four largest coastlines {top[-1]:.1f} to {top[0]:.1f} times" in text


def _section_rows(name: str, width: int) -> list[list[str]]:
    """The table rows of ``width`` cells in RESULTS.md's section ``name``."""
    results = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    part = results.split(f"<!-- section:{name} -->")[1].split(f"<!-- end:{name} -->")[0]
    rows = [[c.strip() for c in row.strip().strip("|").split("|")] for row in part.splitlines()]
    return [r for r in rows if len(r) == width and not r[0].startswith("---")]


def test_layer_numbers_in_the_docs_are_the_benchmark_file():
    """docs/method.md's comparison with Gmsh and its solver errors are the rows ``make
    bench`` last wrote ("layers", "layers-solver")."""
    method = " ".join(DOCS["method.md"].split())
    peer = {r[0]: r for r in _section_rows("layers", 12)}
    ours, gmsh = peer["deformesh"], peer["gmsh"]
    assert (
        f"deformesh {ours[1]} s, Gmsh {gmsh[1]} s as whole processes; both keep the "
        f"{ours[6].split(' of ')[1]} points, Gmsh adds {gmsh[7]} wall nodes where it splits "
        f"edges; {ours[5]} quads and {ours[4]} triangles against {gmsh[5]} and {gmsh[4]}; "
        f"smallest wall angle {ours[9]} degrees against {gmsh[9]}; largest aspect ratio "
        f"{ours[11]} against {gmsh[11]}."
    ) in method
    assert ours[7] == "0" and ours[6] == gmsh[6]
    alone = peer["deformesh quad-only"]
    assert (
        f"In quads alone (`--cells quad-only`): {alone[5]} quads in {alone[1]} s, a node at "
        f"the middle of each of the {alone[7]} wall edges, smallest wall angle {alone[9]} "
        f"degrees, first heights {alone[10]}"
    ) in method and f"largest aspect ratio {alone[11]}, the layers halved" in method
    assert alone[4] == "0" and alone[6] == ours[6]
    solved = {r[0]: r for r in _section_rows("layers-solver", 6)}
    layers, plain = solved["with layers"], solved["without layers"]
    assert (
        f"15 layers from 0.002 give an L2 error of {layers[4]} and an H1 seminorm error of "
        f"{layers[5]} at {layers[2]} nodes, against {plain[4]} and {plain[5]} without layers "
        f"at {plain[2]} nodes."
    ) in method
    assert float(layers[4]) < float(plain[4]) and float(layers[5]) < float(plain[5])


def test_quad_numbers_in_the_docs_are_the_benchmark_file():
    """docs/method.md's comparison with Gmsh's Blossom recombination is the rows ``make
    bench`` last wrote ("quads")."""
    method = " ".join(DOCS["method.md"].split())
    rows = {(r[0], r[1]): r for r in _section_rows("quads", 10)}

    def phrase(name, label):
        ours, gmsh = rows[name, "deformesh"], rows[name, "gmsh"]
        assert ours[6] == gmsh[6] and ours[6].split(" of ")[0] == ours[6].split(" of ")[1]
        return (
            f"{label}, {ours[7]} of the area in quads, the smallest scaled Jacobian {ours[9]}, "
            f"{ours[2]} s, against Gmsh's {gmsh[7]}, {gmsh[9]} and {gmsh[2]} s"
        )

    assert f"{phrase('circle', 'the circle')}; {phrase('naca0012', 'the NACA 0012')}." in method
    assert float(rows["circle", "deformesh"][7].rstrip("%")) >= 80
    assert float(rows["naca0012", "deformesh"][7].rstrip("%")) >= 70


def test_the_recombination_s_time_grows_with_the_triangles():
    """docs/method.md says the recombination's time grows in proportion to the triangles,
    from 5 thousand to half a million: the rows ``make bench`` last wrote ("quads")."""
    method = " ".join(DOCS["method.md"].split())
    assert "grows in proportion to the triangles, from 5 thousand to half a million" in method
    rows = [r for r in _section_rows("quads", 6) if r[0][0].isdigit()]
    tri = [int(r[1]) for r in rows]
    assert tri[0] < 6_000 and tri[-1] > 500_000
    per = [float(r[2]) / n for r, n in zip(rows, tri)]
    assert per[-1] <= 2 * per[1]  # (the smallest mesh's time is mostly fixed costs)
