"""Reading and writing whole files, atomically.

Every file is written to a temporary file in the target's folder, then moved
into place with ``os.replace``: a failure leaves no partial file behind.
``-`` is stdin or stdout.  Outputs are regular files only: a path that is a
device, FIFO, socket or folder is refused, and a symbolic link is written
through (next to its target) only when it points to a regular file.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import stat
import sys
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

from .errors import OptionError, ReadError, WriteError

_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
)


def _kind(mode: int) -> str:
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def output_target(path: str) -> Path:
    """The regular file that writing ``path`` replaces: ``path`` itself, or the file a
    symbolic link points to.  :class:`OptionError` if ``path`` exists and is not a regular
    file, or is a link to anything else (``-`` for stdout is the caller's business)."""
    p = Path(path)
    link = p.is_symlink()
    try:
        mode = p.stat().st_mode  # the link's target's, for a link
    except FileNotFoundError:
        if link:
            raise OptionError(
                f"{path}: is a symbolic link to {os.readlink(p)}, which does not exist; "
                "refusing to write through it"
            ) from None
        return p
    except OSError as exc:
        raise WriteError(f"{path}: cannot write: {exc.strerror}") from None
    if not stat.S_ISREG(mode):
        what = f"a symbolic link to {_kind(mode)}" if link else _kind(mode)
        raise OptionError(f"{path}: is {what}; outputs are regular files only")
    if link:
        return Path(os.path.realpath(p))
    return p


def _identity(path: str) -> tuple:
    """What names one file: its device and inode if it exists, else the absolute path it
    would be created at (links in its folders resolved)."""
    try:
        st = os.stat(path)
    except OSError:
        return ("new", os.path.realpath(path))
    return ("file", st.st_dev, st.st_ino)


def check_outputs(
    named: Sequence[str],
    inputs: Sequence[str | None] = (),
    implied: Sequence[str] = (),
) -> None:
    """Refuse, before any work, a run that would lose a file: an output (``named`` by the
    user, or ``implied`` by them, as a sidecar or a batch's ``NAME.FORMAT``) that is an
    input of the run or the same file as another output; an implied output that is a
    symbolic link (it is created new, never written through a link).  ``-`` is stdin or
    stdout, never a file.  :class:`OptionError` naming both paths."""
    given = {_identity(p): p for p in reversed(inputs) if p is not None and p != "-"}
    written: dict[tuple, str] = {}
    for path in implied:
        if os.path.islink(path):
            raise OptionError(
                f"{path}: is a symbolic link; this run writes that file new, never "
                "through a link (remove the link)"
            )
    for path in [*named, *implied]:
        if path == "-":
            continue
        key = _identity(path)
        other = given.get(key, written.get(key))
        if other is not None:
            what = "an input of this run" if key in given else "another output of this run"
            same = "" if other == path else f" (the same file as {other})"
            raise OptionError(f"{path}: is {what}{same}; refusing to overwrite it")
        written[key] = path


def check_folder(path: str) -> Path:
    """The folder ``path`` would be written in; :class:`WriteError` if it does not exist."""
    folder = Path(path).parent
    if not folder.is_dir():
        raise WriteError(f"{path}: cannot write: folder {folder} does not exist")
    return folder


@contextlib.contextmanager
def atomic_path(path: str) -> Iterator[str]:
    """Yield a temporary path next to ``path`` (next to a symbolic link's target); move it
    into place on success only.  :func:`output_target` says what may be replaced."""
    target = output_target(path)
    folder = check_folder(str(target))
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise WriteError(f"{path}: cannot write: {exc.strerror}") from None
    os.close(fd)
    try:
        yield tmp
        try:
            os.chmod(tmp, 0o644)
            os.replace(tmp, target)
        except OSError as exc:
            raise WriteError(f"{path}: cannot write: {exc.strerror}") from None
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_bytes(data: bytes, path: str, name: str | None = None) -> None:
    """Write bytes to a file atomically, or to stdout for ``-``.  ``name``: how errors
    name the file (``path`` being a staged temporary file of :func:`atomic_path`),
    which is then written directly."""
    if path == "-":
        write_stdout(data)
        return
    if name is not None:
        _write(data, path, name)
        return
    with atomic_path(path) as tmp:
        _write(data, tmp, path)


def to_json(obj) -> str:
    """``obj`` as strict JSON: a number that is not finite is written ``null`` (JSON
    has no NaN or Infinity)."""

    def clean(v):
        if isinstance(v, float):
            return v if math.isfinite(v) else None
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [clean(x) for x in v]
        return v

    return json.dumps(clean(obj), allow_nan=False)


def write_stdout(data: bytes | str) -> None:
    """Bytes (or text, with a newline) on stdout, flushed.  A stdout that is closed or
    cannot take them (a full disk) is a :class:`WriteError`; a closed pipe is left to
    the caller (``| head`` ends a run quietly)."""
    if sys.stdout is None:
        raise WriteError("stdout: is closed; nothing can be written there")
    try:
        if isinstance(data, str):
            sys.stdout.write(data + "\n")
            sys.stdout.flush()
        else:
            sys.stdout.flush()
            sys.stdout.buffer.write(data)
            sys.stdout.buffer.flush()
    except BrokenPipeError:
        raise
    except OSError as exc:
        raise WriteError(f"stdout: cannot write: {exc.strerror or exc}") from None


def _write(data: bytes, path: str, name: str) -> None:
    try:
        with open(path, "wb") as f:
            f.write(data)
    except OSError as exc:
        raise WriteError(f"{name}: cannot write: {exc.strerror}") from None


def write_files(folder: str, files: list[tuple[str, bytes]]) -> None:
    """Several files into ``folder``, each atomically; if one fails, none of them stays."""
    written = []
    try:
        for name, data in files:
            path = os.path.join(folder, name)
            write_bytes(data, path)
            written.append(path)
    except BaseException:
        for path in written:
            with contextlib.suppress(OSError):
                os.unlink(path)
        raise


def make_folder(path: str) -> None:
    """Create an output folder (and its parents) if missing."""
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as exc:
        raise WriteError(f"{path}: cannot create the output folder: {exc.strerror}") from None


def existing_file(path: str) -> Path:
    """``path`` as a Path, or a :class:`ReadError` if it is missing, a folder, or a
    device or socket (which never end: ``/dev/zero`` would be read forever).  A pipe
    is a file here, as ``<(command)`` gives one."""
    p = Path(path)
    if not p.exists():
        if os.path.islink(path):  # (lstat sees it; stat does not)
            raise ReadError(
                f"{path}: is a symbolic link that leads to no file (dangling, or a loop)"
            )
        raise ReadError(f"{path}: no such file")
    if p.is_dir():
        raise ReadError(f"{path}: is a directory")
    mode = p.stat().st_mode
    for test, what in _KINDS[1:]:
        if test(mode) and test is not stat.S_ISFIFO:
            raise ReadError(f"{path}: is {what}, not a file")
    return p


#: Whole numbers in JSON longer than this are read as floats (beyond 1e308: infinite,
#: and refused as any non-finite number is), never converted digit by digit.
MAX_INT_DIGITS = 300


def _json_int(text: str) -> int | float:
    return int(text) if len(text) <= MAX_INT_DIGITS else float(text)


def parse_json(text: str | bytes):
    """``json.loads`` with every number a double can hold, and none longer converted
    (Python refuses whole numbers over 4,300 digits with a ValueError)."""
    return json.loads(text, parse_int=_json_int)


def read_bytes(path: str) -> bytes:
    """Read a whole file, or all of stdin for ``-`` (works on non-seekable pipes)."""
    if path == "-":
        return sys.stdin.buffer.read()
    p = existing_file(path)
    try:
        return p.read_bytes()
    except OSError as exc:
        raise ReadError(f"{path}: cannot read: {exc.strerror}") from None
