"""How far long work is, on stderr: a live line on a terminal, plain lines in a log.

The core only calls callbacks (the deformation's ``callback``, ``on_stage``,
``adapt``'s ``progress``); what is drawn is decided here.  Nothing here changes an
output file: the clock only decides when a line is written.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Callable

import click

#: ``--progress/--no-progress``: force the progress on (even with -q) or off; default:
#: on unless -q, live on a terminal, plain lines otherwise.
progress_option = click.option(
    "--progress/--no-progress",
    "progress_flag",
    default=None,
    help="Show how far the work is (a live line on a terminal, a plain line at every "
    "tenth of a batch or every minute otherwise), or never. Default: shown unless -q.",
)

#: A plain progress line at least this often (seconds), and at every tenth of the work.
PLAIN_EVERY = 60.0

#: A single mesh, a move or an adaptation says how far it is only once it has run this
#: long (seconds): shorter runs print nothing more than their summary.
SHOW_AFTER = 2.0


def mode(quiet: bool, forced: bool | None) -> str | None:
    """``"live"`` (a line redrawn in place), ``"plain"`` (lines) or None (nothing)."""
    if forced is False or (forced is None and quiet):
        return None
    return "live" if sys.stderr.isatty() else "plain"


def clock(seconds: float) -> str:
    """``m:ss`` (or ``h:mm:ss``)."""
    s = int(round(seconds))
    h, rest = divmod(s, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class BatchProgress:
    """A batch's progress: files done of ``total``, ok and failed so far, the time
    elapsed and an estimate of the time left, and the file last done.  Live: click's
    progress bar, redrawn in place; plain: a line at every tenth of the batch or
    every :data:`PLAIN_EVERY` seconds, whichever comes first (``heartbeat``: a thread
    writes the minute's line while no file finishes)."""

    def __init__(
        self,
        total: int,
        how: str | None,
        now: Callable[[], float] = time.monotonic,
        heartbeat: bool = True,
    ):
        self.total, self.how, self.now = total, how, now
        self.start = self.last_line = now()
        self.done = self.ok = self.failed = 0
        self.next_tenth = 1
        self.bar = None
        self.lock = threading.Lock()
        self.stop = threading.Event()
        self.beat = None
        if how == "plain" and heartbeat:
            self.beat = threading.Thread(target=self._beat, daemon=True)
            self.beat.start()
        if how == "live":
            self.bar = click.progressbar(
                length=total, label="meshing", file=sys.stderr, show_eta=False,
                show_pos=True, item_show_func=lambda text: text, width=20,
            )  # fmt: skip
            self.bar.__enter__()

    @property
    def clear(self) -> str:
        """What a message printed while the live line is drawn starts with."""
        return "\r\033[K" if self.bar is not None else ""

    def step(self, status: str, name: str) -> None:
        """One more input finished, with ``status`` (``ok``, ``failed``, ...)."""
        with self.lock:
            self.done += 1
            self.ok += status == "ok"
            self.failed += status == "failed"
            if self.bar is not None:  # (the file's name alone: the table gives its path)
                self.bar.update(1, f"{self._counts()}: {os.path.basename(name)}")
                return
            if self.how != "plain":
                return
            tenth = self.done * 10 >= self.next_tenth * self.total
            if tenth or self.now() - self.last_line >= PLAIN_EVERY:
                while self.next_tenth * self.total <= self.done * 10:
                    self.next_tenth += 1
                self._line()

    def _counts(self) -> str:
        elapsed = self.now() - self.start
        out = f"ok {self.ok}, failed {self.failed}, {clock(elapsed)} elapsed"
        if self.done:
            left = elapsed / self.done * (self.total - self.done)
            out += f", {'~' if self.bar is not None else 'about '}{clock(left)} left"
        return out

    def _line(self) -> None:
        click.echo(f"deformesh: {self.done} of {self.total} done ({self._counts()})", err=True)
        self.last_line = self.now()

    def _beat(self) -> None:
        """The minute's line while no file finishes (a long one keeps a log alive)."""
        while not self.stop.wait(PLAIN_EVERY / 4):
            with self.lock:
                if self.now() - self.last_line >= PLAIN_EVERY:
                    self._line()

    def close(self) -> None:
        self.stop.set()
        if self.beat is not None:
            self.beat.join()
            self.beat = None
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None


class LiveLine:
    """One line redrawn in place on a terminal once the work has run
    :data:`SHOW_AFTER` seconds (``say(text)``), cleared at the end; nothing off a
    terminal."""

    def __init__(self, how: str | None, now: Callable[[], float] = time.monotonic):
        self.live = how == "live"
        self.now = now
        self.start = now()
        self.drawn = False

    def say(self, text: str) -> None:
        if self.live and self.now() - self.start >= SHOW_AFTER:
            _draw(f"\r\033[K{text}")
            self.drawn = True

    def deforming(self, name: str) -> Callable:
        """The deformation's ``callback(done, stats)``, saying how far it is."""
        return lambda done, stats: self.say(f"deformesh: {name}: deform, pseudo-time {done:.2f}")

    def close(self) -> None:
        if self.drawn:
            _draw("\r\033[K")
            self.drawn = False


def _draw(text: str) -> None:
    sys.stderr.write(text)
    sys.stderr.flush()
