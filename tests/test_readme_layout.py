"""The README's "What is where" table names every package and top-level module of
soilstats/ (issue #38: the table matches the tree)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _table() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    start = text.index("## What is where")
    return text[start : text.index("\n## ", start + 1)]


def test_every_package_and_module_is_in_the_table():
    table = _table()
    named = set(re.findall(r"`(soilstats/[\w./]+?)/?`", table))
    tree = {
        f"soilstats/{p.name}"
        for p in (ROOT / "soilstats").iterdir()
        if ((p.is_dir() and (p / "__init__.py").exists()) or p.name == "data")
        or (p.suffix == ".py")
    }
    missing = sorted(tree - named)
    assert not missing, f"README's 'What is where' does not name {missing}"
    gone = sorted(n for n in named if not (ROOT / n).exists())
    assert not gone, f"README's 'What is where' names what is not in the tree: {gone}"
