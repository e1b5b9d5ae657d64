"""What a careful reader of the figures needs (issue #47 item 5): a posterior that spans
decades on a logarithmic axis, named in the caption; the physical-support check as rows of
words, never a printed mapping."""

from __future__ import annotations

import arviz as az
import numpy as np

from soilstats.report.posterior_figures import pair_figure, spans_decades, trace_figure
from soilstats.report.posterior_pdf import _support_rows


def _idata(k_draws: np.ndarray) -> az.InferenceData:
    rng = np.random.default_rng(0)
    n = rng.normal(0.9, 0.02, k_draws.shape)
    idata = az.from_dict(posterior={"k": k_draws, "n": n})
    idata.posterior.attrs["model"] = "bernstein"
    return idata


def test_a_posterior_spanning_decades_is_drawn_on_a_log_axis_and_the_caption_says_so():
    rng = np.random.default_rng(1)
    wide = np.exp(rng.normal(np.log(2e6), 1.5, (4, 300)))  # ~ 4 decades (1st–99th pct)
    narrow = rng.normal(2e6, 1e5, (4, 300))
    assert spans_decades(wide) and not spans_decades(narrow)
    assert not spans_decades(-wide)  # a signed parameter never goes on a log axis
    fig, caption = trace_figure(_idata(wide))
    assert fig.axes[0].get_yscale() == "log" and fig.axes[2].get_yscale() == "linear"
    assert "k spans a decade or more and is drawn on a logarithmic axis" in caption
    fig, caption = pair_figure(_idata(wide))
    scales = [(ax.get_xscale(), ax.get_yscale()) for ax in fig.axes if ax.axison]
    # k's diagonal and the k–n pair (k on x) on log axes, n's diagonal linear
    assert sorted(scales) == [("linear", "linear"), ("log", "linear"), ("log", "linear")]
    assert "logarithmic axis" in caption
    fig, caption = trace_figure(_idata(narrow))
    assert fig.axes[0].get_yscale() == "linear" and "logarithmic" not in caption


def test_the_support_check_prints_as_rows_of_words():
    support = {
        "draws": 12000,
        "outside": 3,
        "share_outside": 0.00025,
        "passed": True,
        "reasons": {"n <= 0": 1, "K <= 0": 2},
        "contact_widths_m": [0.025, 0.075],
    }
    rows = dict(_support_rows(support))
    assert rows["reasons: K <= 0"] == "2" and rows["passed"] == "yes"
    assert rows["contact widths m"] == "0.025 – 0.075"
    assert not any("{" in v or "[" in v for v in rows.values())


def test_levels_are_named_in_natural_order():
    """1, 2, 3 … 10, not 1, 10, 11, 2 (the posterior's pooling warning named them so)."""
    from soilstats import load_campaign
    from soilstats.cli.posterior import pooling_warnings

    warnings = pooling_warnings(load_campaign("simulated-paper"), "soil01", ["bekker"])
    text = next(w for w in warnings if "values of preparation" in w)
    assert "(1, 2, 3, 4, 5, 6)" in text


def test_one_plate_size_is_a_width_not_a_range():
    """The Cullinan posterior said "at contact widths 0.075694–0.075694 m"."""
    from soilstats.bayes.support import widths_text

    assert widths_text(0.075694, 0.075694) == "contact width 0.0757 m"
    assert widths_text(0.025, 0.075) == "contact widths 0.025–0.075 m"
