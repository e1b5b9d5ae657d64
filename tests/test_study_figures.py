"""Study figures say why a large move sits beside a 'no effect' verdict (issue #36)."""

from __future__ import annotations

from types import SimpleNamespace

import pandas as pd

from soilstats.report.study_figures import moves_without_effect


def _result(kphi_values, verdict):
    rows = [
        {"soil": "s", "condition": c, "parameter": "kphi", "value": v, "stderr": 1.0}
        for c, v in zip(("a", "b"), kphi_values, strict=True)
    ]
    effects = pd.DataFrame(
        [{"soil": "s", "response": r, "verdict": verdict} for r in ("log10_p_ref", "n")]
    )
    return SimpleNamespace(parameters=pd.DataFrame(rows), effects=effects)


def test_a_large_move_beside_no_effect_is_named_and_a_small_one_or_an_effect_is_not():
    assert moves_without_effect(_result([1e6, 9e7], "no relevant effect")) == ["s kphi ×90"]
    assert moves_without_effect(_result([-1e6, 9e7], "no effect")) == ["s kphi changes sign"]
    assert moves_without_effect(_result([1e6, 1.5e6], "no effect")) == []
    assert moves_without_effect(_result([1e6, 9e7], "effect")) == []
