"""benchmarks/RESULTS.md is shared by the benchmark scripts: each owns one section."""

import os
import platform
import re
import sys
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "RESULTS.md"
HEAD = "# Benchmarks\n\nWritten by `make bench`; every section names the machine it ran on.\n"


def write_section(name: str, text: str) -> None:
    """Replace (or add) the section ``name`` of RESULTS.md, keeping the others."""
    old = RESULTS.read_text() if RESULTS.exists() else HEAD
    if "<!-- section:" not in old:  # an older single-section file: start afresh
        old = HEAD
    block = f"<!-- section:{name} -->\n{text.rstrip()}\n<!-- end:{name} -->\n"
    pattern = re.compile(
        rf"<!-- section:{re.escape(name)} -->.*?<!-- end:{re.escape(name)} -->\n", re.S
    )
    new = (
        pattern.sub(lambda m: block, old) if pattern.search(old) else old.rstrip() + "\n\n" + block
    )
    RESULTS.write_text(new)
    print(f"wrote benchmarks/RESULTS.md ({name} section)", file=sys.stderr)


def machine() -> str:
    """The machine a benchmark ran on, for the record."""
    with open("/proc/cpuinfo") as f:
        cpu = next(
            (ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")),
            platform.processor(),
        )
    mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    return (
        f"{platform.node()}: {cpu}, {os.cpu_count()} cores, {mem:.0f} GiB, "
        f"Python {platform.python_version()}"
    )


def heading(title: str, intro: str) -> list[str]:
    """A section's first lines: its title, the machine and the date, what it measures."""
    return [title, "", f"Machine: {machine()}.  Date: {time.strftime('%Y-%m-%d')}.", "", intro, ""]
