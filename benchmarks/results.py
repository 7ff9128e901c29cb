"""benchmarks/RESULTS.md is shared by the benchmark scripts: each owns one section."""

import re
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "RESULTS.md"
HEAD = "# Benchmarks\n\nWritten by `make bench`; every section names the machine it ran on.\n"


def write_section(name: str, text: str) -> None:
    """Replace (or add) the section ``name`` of RESULTS.md, keeping the others."""
    old = RESULTS.read_text() if RESULTS.exists() else HEAD
    if "<!-- section:" not in old:  # an older single-section file: start afresh
        old = HEAD
    block = f"<!-- section:{name} -->\n{text.rstrip()}\n<!-- end:{name} -->\n"
    pattern = re.compile(rf"<!-- section:{re.escape(name)} -->.*?<!-- end:{re.escape(name)} -->\n",
                         re.S)
    new = pattern.sub(lambda m: block, old) if pattern.search(old) else old.rstrip() + "\n\n" + block
    RESULTS.write_text(new)
