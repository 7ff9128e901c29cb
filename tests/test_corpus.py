"""The real corpus (tests/data/corpus: airfoils, icons, coastlines; see SOURCES.md), as one
batch: every contour gives a mesh meeting the contract or a documented refusal.

The pass rate itself is measured by `make bench` (benchmarks/RESULTS.md) at default
options.  Here the grid is capped (--max-nodes) to keep the suite fast.
"""

import json
import re
from pathlib import Path

import pytest

from .conftest import ROOT

CORPUS = ROOT / "tests" / "data" / "corpus"

#: The refusals a user can act on, as their messages begin (after "FILE: ").
REFUSALS = re.compile(
    r"the background grid would need .* nodes"
    r"|the contour intersects itself near \("
    r"|.* touches or crosses .* near \("
    r"|the filled area pinches to a point at \("
    r"|the grid path touches itself near point \d+"
    r"|the deformation folds a triangle near \("
    r"|the final mesh would fold a triangle near \("
)


@pytest.mark.slow
def test_corpus_meshes_or_refuses_with_a_reason(run, tmp_path):
    files = sorted(p for p in CORPUS.iterdir() if p.suffix in (".csv", ".svg"))
    assert len(files) >= 40
    listed = (CORPUS / "SOURCES.md").read_text()
    assert all(f"| {p.name} |" in listed for p in files)  # every file has its source
    r = run(
        "all", CORPUS, "--out-dir", tmp_path, "--jobs", "2", "--json", "-q", "--max-nodes", "300000"
    )
    recs = [json.loads(ln) for ln in r.stdout.splitlines()]
    # the folder's SOURCES.md is listed as not meshed (no contour format)
    notes = [x for x in recs if Path(x["input"]).name == "SOURCES.md"]
    assert len(notes) == 1 and notes[0]["status"] == "skipped"
    recs = [x for x in recs if x not in notes]
    assert [Path(x["input"]).name for x in recs] == [p.name for p in files]
    for x in recs:
        if x["status"] == "ok":
            assert x["contract"] == "ok"
        else:
            why = x["error"].removeprefix(f"{x['input']}: ")
            assert REFUSALS.match(why), x["error"]
    ok = sum(x["status"] == "ok" for x in recs)
    # a ratchet: the count may only go up (at default options coast_india meshes too,
    # on 1.75e6 grid nodes: not within this cap)
    assert ok >= 47
    assert r.exit_code == (0 if ok == len(recs) else 1)
