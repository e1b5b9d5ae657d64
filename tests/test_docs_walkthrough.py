"""docs/walkthrough.md runs as written (issue #47 item 4): its Python blocks are executed in
order in one namespace, with every warning an error (a walk-through that warns without
saying why would teach the reader to ignore warnings)."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "walkthrough.md"


def _blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_the_notebook_walkthrough_runs_clean(capsys):
    import matplotlib.pyplot as plt

    blocks = _blocks(PAGE.read_text(encoding="utf-8"))
    assert len(blocks) >= 6
    namespace: dict = {"__name__": "walkthrough"}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for number, block in enumerate(blocks, 1):
            try:
                exec(compile(block, f"{PAGE.name} block {number}", "exec"), namespace)
            except Exception as err:  # name the block that failed
                raise AssertionError(f"block {number} of {PAGE.name} failed: {err!r}") from err
    plt.close("all")
    out = capsys.readouterr().out
    # What the page says it shows, it shows.
    assert namespace["own"].param_names == ("a", "b")
    assert "needs 2 inputs (b, z)" in out
    assert "refused:" in out and "elastic_K > Bekker_Kphi" in out
    assert namespace["sets"].check.passed
    assert namespace["ax"].get_ylabel().startswith("measured − fitted")
