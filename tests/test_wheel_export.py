"""The Chrono SCM export against the wheel (issue #43 item 8): SCM's modulus at its own contact
width l·w/(l + w) against the one at the wheel width the wheel model uses, both figures named;
a shear posterior pooling test series of different set-ups refused without --select."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from soilstats.bayes.export import (
    chrono_contact_width,
    contact_width_warning,
    pooled_series_failure,
)
from soilstats.cli.main import main


def _table(kc: float, kphi: float, rows: int = 5) -> pd.DataFrame:
    return pd.DataFrame({"Bekker_Kc": np.full(rows, kc), "Bekker_Kphi": np.full(rows, kphi)})


def test_chrono_sizes_a_rectangle_by_its_perimeter():
    # 1/b = perimeter / (2 area) = (l + w)/(l w); a square of side a gives a/2
    assert chrono_contact_width(0.04, 0.04) == pytest.approx(0.02)
    assert chrono_contact_width(0.039, 0.05) == pytest.approx(0.039 * 0.05 / 0.089)
    with pytest.raises(ValueError, match="positive, finite"):
        chrono_contact_width(0.0, 0.05)


def test_a_soil_softer_at_chronos_width_is_named_with_both_moduli():
    # kc < 0 as on the CMU plates: at b = 21.9 mm the modulus is far below the one at 50 mm
    kc, kphi, length, width = -2.0e5, 1.3e7, 0.039, 0.05
    b = length * width / (length + width)
    text = contact_width_warning(_table(kc, kphi), length, width)
    assert text is not None and "softer" in text
    assert f"{kc / b + kphi:.4g}" in text and f"{kc / width + kphi:.4g}" in text
    assert "21.9 mm" in text and "b = 50 mm" in text


def test_no_warning_within_a_quarter_and_one_just_beyond():
    length, width = 0.039, 0.05
    b = length * width / (length + width)
    # choose kc so that the ratio is exactly 1.2, then 1.3 (stiffer at SCM's width)
    for ratio, warned in ((1.2, False), (1.3, True)):
        kphi = 1.0e6
        # (kc/b + kphi) = ratio (kc/w + kphi)  →  kc (1/b − ratio/w) = (ratio − 1) kphi
        kc = (ratio - 1) * kphi / (1 / b - ratio / width)
        text = contact_width_warning(_table(kc, kphi), length, width)
        assert (text is not None) == warned
    assert contact_width_warning(_table(0.0, 5e6), length, width) is None  # Bernstein: Kc = 0


def test_pooled_shear_series_are_refused_and_one_series_is_not():
    tests = pd.DataFrame({"series": ["ring-a", "ring-a", "grousers", "speed"]})
    text = pooled_series_failure(tests)
    assert text is not None and "3 test series" in text and "--select shear:series=" in text
    assert pooled_series_failure(tests.iloc[:2]) is None
    assert pooled_series_failure(pd.DataFrame({"soil": ["a"]})) is None


def test_the_command_refuses_pooled_series_before_sampling(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["posterior", "--data", "simulated-paper", "--soil", "soil01"]
    argv += ["--model", "bekker+janosi", "--simulator", "chrono-scm", "--out", str(out)]
    assert main([*argv, "--progress", "off"]) == 2
    err = capsys.readouterr().err
    assert "pools 4 test series" in err and "--select shear:series=" in err
    assert not out.exists() or not any(out.iterdir())
    assert main([*argv, "--scm-contact", "0.039"]) == 2
    assert "LENGTH:WIDTH" in capsys.readouterr().err
