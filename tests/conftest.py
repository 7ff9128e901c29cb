import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from deformesh_cli.cli import cli

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "samples"
SHARED = ROOT.parent / "shared" / "contours"


def shared(name: str) -> Path:
    """A reference contour from ../shared/contours (kept beside every clone here)."""
    p = SHARED / name
    if not p.exists():  # pragma: no cover - the workplace always has shared/
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
        r = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], cwd=cwd, env=env,
                           capture_output=True, stdin=subprocess.DEVNULL)
        if check and r.returncode != 0:
            raise AssertionError(f"{cmd!r} exited {r.returncode}: {r.stderr.decode()}")
        return r

    return _sh
