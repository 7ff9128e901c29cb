"""Print every distribution ``deformesh`` needs at run time (its dependency closure in
this environment, extras left out) with its licence; exit 1 if any is GPL-only (the
default install must be shippable with MIT code).

    python scripts/licences.py
"""

from __future__ import annotations

import re
import sys
from importlib import metadata

COPYLEFT = re.compile(r"\b(A|L)?GPL|GNU (Affero |Lesser )?General Public", re.IGNORECASE)


def licence(dist: metadata.Distribution) -> str:
    m = dist.metadata
    expr = m.get("License-Expression")
    if expr:
        return expr
    classifiers = [c.split(" :: ")[-1] for c in m.get_all("Classifier") or [] if "License" in c]
    text = (m.get("License") or "").strip().splitlines()
    return "; ".join(classifiers) or (text[0] if text else "unknown")


def closure(name: str) -> dict[str, metadata.Distribution]:
    seen: dict[str, metadata.Distribution] = {}
    todo = [name]
    while todo:
        key = re.split(r"[\s<>=!~;\[(]", todo.pop(), maxsplit=1)[0].lower().replace("_", "-")
        if key in seen:
            continue
        try:
            dist = metadata.distribution(key)
        except metadata.PackageNotFoundError:  # (a marker left it out here: not shipped)
            continue
        seen[key] = dist
        for req in dist.requires or []:
            if "extra ==" not in req and "extra==" not in req:
                todo.append(req)
    return seen


def main() -> int:
    bad = []
    for key, dist in sorted(closure("deformesh").items()):
        lic = licence(dist)
        print(f"{key:24} {dist.version:12} {lic}")
        if COPYLEFT.search(lic) and " OR " not in lic:  # (a choice of licences is fine)
            bad.append(key)
    if bad:
        print(f"GPL at run time: {', '.join(bad)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
