"""Progress on long work: a live line on a terminal, plain lines in a log, nothing with -q."""

from __future__ import annotations

import os
import pty
import shutil
import subprocess
import sys

import pytest

from deformesh_cli.cli import progress

from .conftest import SAMPLES


@pytest.fixture(scope="module")
def fifty(tmp_path_factory):
    """A folder of 50 contours: the samples' CSV files, again and again."""
    d = tmp_path_factory.mktemp("fifty")
    csv = sorted(SAMPLES.glob("*.csv"))
    for k in range(50):
        src = csv[k % len(csv)]
        shutil.copy(src, d / f"{k:02d}_{src.name}")
    return d


def _on_a_terminal(args: list) -> tuple[int, str]:
    """Run deformesh with its stderr on a pseudo-terminal (stdout piped): what a person
    at a terminal sees."""
    master, slave = pty.openpty()
    p = subprocess.Popen(
        [sys.executable, "-m", "deformesh_cli", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=slave,
        stdin=subprocess.DEVNULL,
    )
    os.close(slave)
    seen = b""
    while True:
        try:
            chunk = os.read(master, 1 << 16)
        except OSError:  # (the terminal closed with the process)
            break
        if not chunk:
            break
        seen += chunk
    p.wait()
    os.close(master)
    return p.returncode, seen.decode(errors="replace")


def test_a_batch_on_a_terminal_shows_a_live_line(fifty, tmp_path):
    code, err = _on_a_terminal(["all", fifty, "--out-dir", tmp_path / "out"])
    assert code == 0
    live = err.split("deformesh: 50 contour(s)")[0]
    assert "\r" in live and "meshing" in live
    assert "50/50" in live and "ok 50, failed 0" in live and "left: " in live
    assert "elapsed" in live
    # then today's summary and table
    assert "deformesh: 50 contour(s): 50 ok, 0 failed" in err
    assert err.split("50 contour(s)")[1].count("\n  ok ") == 50


def test_a_batch_in_a_log_writes_plain_lines(run, fifty, tmp_path):
    r = run("all", fifty, "--out-dir", tmp_path / "out")
    assert r.exit_code == 0
    assert "\r" not in r.stderr and "\x1b" not in r.stderr
    lines = [ln for ln in r.stderr.splitlines() if " done (ok " in ln]
    assert [ln.split(" of ")[0].split()[-1] for ln in lines] == [str(5 * k) for k in range(1, 11)]
    assert all("left)" in ln and "elapsed" in ln for ln in lines)
    quiet = run("all", fifty, "--out-dir", tmp_path / "q", "-q")
    assert quiet.exit_code == 0 and quiet.stderr == ""
    off = run("all", fifty, "--out-dir", tmp_path / "off", "--no-progress")
    assert " done (ok " not in off.stderr and "50 contour(s)" in off.stderr
    forced = run("all", fifty, "--out-dir", tmp_path / "forced", "-q", "--progress")
    assert len([ln for ln in forced.stderr.splitlines() if " done (ok " in ln]) == 10


class _Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_plain_lines_come_every_tenth_or_every_minute(capsys):
    clock = _Clock()
    bar = progress.BatchProgress(1000, "plain", now=clock, heartbeat=False)
    for k in range(1000):
        clock.t += 1.0  # (a second a file: a minute passes before a tenth)
        bar.step("ok", f"c{k}.csv")
    bar.close()
    lines = capsys.readouterr().err.splitlines()
    done = [int(ln.split(" of ")[0].split()[-1]) for ln in lines]
    assert done[:2] == [60, 100] and done[-1] == 1000
    assert all(b - a <= 60 for a, b in zip(done, done[1:]))


def test_a_single_mesh_says_its_stage_only_after_two_seconds(capsys):
    clock = _Clock()
    line = progress.LiveLine("live", now=clock)
    line.say("deformesh: c.csv: select")
    assert capsys.readouterr().err == ""  # (a short run prints nothing more)
    clock.t = progress.SHOW_AFTER
    line.say("deformesh: c.csv: deform, pseudo-time 0.50")
    line.close()
    err = capsys.readouterr().err
    assert err == "\r\x1b[Kdeformesh: c.csv: deform, pseudo-time 0.50\r\x1b[K"
    off = progress.LiveLine("plain", now=clock)
    off.say("nothing off a terminal")
    assert capsys.readouterr().err == ""


def test_adapt_reports_each_solve():
    """``adapt``'s progress callback: after each solve, the pseudo-time and the count."""
    import numpy as np

    from deformesh_cli import adapt

    n = 12
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1), indexing="ij")
    k = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)[:-1, :-1].ravel()
    tri = np.concatenate([np.c_[k, k + n + 1, k + n + 2], np.c_[k, k + n + 2, k + 1]])
    seen = []
    res = adapt.adapt(
        np.c_[x.ravel(), y.ravel()], tri, lambda q: 1 + 4 * np.exp(-20 * (q[:, 0] - 0.5) ** 2),
        progress=lambda t, solves: seen.append((t, solves)),
    )  # fmt: skip
    assert [s for _, s in seen] == list(range(1, res.report["solves"] + 1))
    assert [t for t, _ in seen] == sorted(t for t, _ in seen) and seen[0][0] == 0.0


def test_move_on_a_terminal_says_each_frame(tmp_path):
    frames = sorted((SAMPLES / "pulsating").glob("frame_*.csv"))
    mesh = tmp_path / "m.vtu"
    assert _on_a_terminal(["all", SAMPLES / "peanut.csv", "-o", mesh, "-q"])[0] == 0
    code, err = _on_a_terminal(["move", mesh, *frames, "--out-dir", tmp_path / "o"])
    assert code == 0
    for k in range(1, 21):
        assert f"frame {k}/20" in err


def test_a_long_file_still_gets_the_minute_s_line(capsys, monkeypatch):
    """No file finishes for longer than the interval: a thread writes the line, so a CI
    log shows the batch is alive (the interval shortened here)."""
    import time

    monkeypatch.setattr(progress, "PLAIN_EVERY", 0.2)
    bar = progress.BatchProgress(5, "plain")
    time.sleep(0.7)
    bar.close()
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) >= 2 and all(ln.startswith("deformesh: 0 of 5 done (ok 0") for ln in lines)
