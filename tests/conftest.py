import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, settings

from deformesh_cli.cli import cli

# Hypothesis profiles: "dev" (default) for quick local runs; "ci" (what `make test` runs)
# puts 1,000 random polygons with holes through the whole pipeline, derandomised so a CI
# run is repeatable.  Tests with their own max_examples keep it under any profile.
settings.register_profile(
    "dev", max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile(
    "ci",
    max_examples=1000,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("dev")

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "samples"
DATA = ROOT / "tests" / "data"
CONTOURS = DATA / "contours"


def contour_file(name: str) -> Path:
    """A reference contour from tests/data/contours (see its SOURCES.md)."""
    p = CONTOURS / name
    if not p.exists():
        pytest.fail(f"reference contour {p} is missing")
    return p


def deformesh_exe() -> str:
    exe = Path(sys.executable).parent / "deformesh"
    return str(exe) if exe.exists() else shutil.which("deformesh")


@pytest.fixture
def run():
    """Run the CLI in-process; returns the click Result (stdout and stderr apart)."""
    runner = CliRunner()

    def _run(*args, input=None):
        return runner.invoke(cli, [str(a) for a in args], input=input, catch_exceptions=False)

    return _run


@pytest.fixture
def sh():
    """Run a shell command line with the installed deformesh on PATH."""

    def _sh(cmd: str, cwd=None, check=True):
        env = dict(os.environ)
        env["PATH"] = str(Path(deformesh_exe()).parent) + os.pathsep + env["PATH"]
        r = subprocess.run(
            ["bash", "-o", "pipefail", "-c", cmd],
            cwd=cwd,
            env=env,
            capture_output=True,
            stdin=subprocess.DEVNULL,
        )
        if check and r.returncode != 0:
            raise AssertionError(f"{cmd!r} exited {r.returncode}: {r.stderr.decode()}")
        return r

    return _sh


def solver_read(path):
    """What the solvers users feed see in a .msh file: the gmsh Python module's physical
    groups (name -> dimension) and the scikit-fem mesh it loads."""
    import gmsh  # the test extra installs both
    import skfem

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(path))
        phys = {gmsh.model.getPhysicalName(d, t): d for d, t in gmsh.model.getPhysicalGroups()}
    finally:
        gmsh.finalize()
    return phys, skfem.MeshTri.load(str(path))
