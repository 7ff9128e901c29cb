"""Every deformesh command in the README's sh blocks runs and exits 0."""

import os
import re

import pytest

from .conftest import ROOT

README = (ROOT / "README.md").read_text()
BLOCKS = re.findall(r"```sh\n(.*?)```", README, flags=re.S)
COMMANDS = [
    ln.split("  #")[0].strip()
    for b in BLOCKS
    for ln in b.splitlines()
    if ln.startswith("deformesh ")
]


def test_readme_has_exactly_the_two_setup_commands():
    setup = [
        ln.split("#")[0].strip() for b in BLOCKS for ln in b.splitlines() if ln.startswith("make ")
    ]
    assert setup == ["make demo", "make test"]


@pytest.mark.parametrize("cmd", COMMANDS)
def test_readme_command_runs(sh, tmp_path, cmd):
    os.symlink(ROOT / "samples", tmp_path / "samples")
    (tmp_path / "out").mkdir()
    r = sh(cmd, cwd=tmp_path)
    assert r.returncode == 0
    assert list((tmp_path / "out").iterdir())


def test_readme_mentions_every_option():
    from deformesh_cli.cli import cli

    for name, cmd in cli.commands.items():
        assert f"deformesh {name}" in README
        for p in cmd.params:
            for opt in p.opts:
                if opt.startswith("--") and opt not in ("--help",):
                    assert opt in README, f"{name} {opt} missing from README"


def test_readme_lists_every_json_key(run, tmp_path):
    import json

    from .conftest import SAMPLES

    r = run("all", SAMPLES / "circle.csv", "-o", tmp_path / "m.vtk", "--json", "-q")
    assert r.exit_code == 0, r.stderr
    for key in json.loads(r.stdout):
        assert f"`{key}`" in README, f"--json key {key} missing from README"


SCRIPT_BLOCKS = [b for b in BLOCKS if "python scripts/" in b]


@pytest.mark.parametrize("block", SCRIPT_BLOCKS)
def test_readme_blocks_with_scripts_run_in_order(sh, tmp_path, block):
    # a script line uses what the lines before it wrote: run the block as a whole
    for name in ("samples", "scripts"):
        os.symlink(ROOT / name, tmp_path / name)
    (tmp_path / "out").mkdir()
    (tmp_path / "docs").mkdir()
    sh("set -e\n" + block, cwd=tmp_path)
    assert list((tmp_path / "docs").iterdir())  # the picture the README shows
