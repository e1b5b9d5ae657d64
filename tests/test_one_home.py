"""Facts with one home (issue #38 item 4): each is defined once and imported where used, so
that a change in one place cannot leave a stale copy behind."""

from __future__ import annotations

import inspect
from pathlib import Path

import pytest

import soilstats
from soilstats import kinds
from soilstats.errors import refuse_unknown_keys

PACKAGE = Path(soilstats.__file__).parent


def test_the_kinds_of_test_and_of_model_are_defined_once():
    from soilstats.campaign import schema
    from soilstats.models import base
    from soilstats.simulation import records

    assert schema.KINDS is kinds.TEST_KINDS and records.KINDS is kinds.TEST_KINDS
    assert base.KINDS is kinds.MODEL_KINDS
    assert kinds.MODEL_KINDS[: len(kinds.TEST_KINDS)] == kinds.TEST_KINDS


def test_min_samples_is_defined_once():
    from soilstats.campaign import schema, units
    from soilstats.identification import pooling

    for module in (units, pooling):
        assert "MIN_SAMPLES =" not in inspect.getsource(module)
        assert module.MIN_SAMPLES == schema.MIN_SAMPLES == 3


def test_unknown_keys_are_refused_in_the_order_of_the_table():
    def error(unknown: list[str]) -> KeyError:
        return KeyError(unknown)

    refuse_unknown_keys({"a": 1, "b": 2}, ("a", "b", "c"), error)  # all allowed: no error
    with pytest.raises(KeyError) as info:
        refuse_unknown_keys({"z": 1, "a": 2, "y": 3}, ("a",), error)
    assert info.value.args[0] == ["z", "y"]


def test_the_report_figures_have_one_style():
    from soilstats.report.document import FIGURE_STYLE

    homes = [p.name for p in (PACKAGE / "report").glob("*.py") if '"font.size"' in p.read_text()]
    assert homes == ["document.py"]
    assert FIGURE_STYLE["font.size"] == 9 and not FIGURE_STYLE["axes.spines.top"]


def test_p_values_are_adjusted_in_one_place():
    """statistics.verdict.adjust_p_values is the one adjustment: no other module calls
    multipletests or imports a private adjustment across packages."""
    home = PACKAGE / "statistics" / "verdict.py"
    for path in PACKAGE.rglob("*.py"):
        if path == home:
            continue
        text = path.read_text(encoding="utf-8")
        assert "multipletests(" not in text, path
        assert "import _adjust" not in text, path


WRITERS = ["check", "identify", "study", "discovery", "posterior", "wheel"]


@pytest.mark.parametrize("module", WRITERS)
def test_every_report_writer_has_one_signature(module):
    """write_report(result, path, *, provenance=None, overwrite=False, ...) -> pages: the
    result and the file first, then keywords only; none overwrites by default."""
    import importlib

    write = importlib.import_module(f"soilstats.report.{module}_pdf").write_report
    params = list(inspect.signature(write).parameters.values())
    assert [p.kind for p in params[:2]] == [inspect.Parameter.POSITIONAL_OR_KEYWORD] * 2
    assert params[1].name == "path"
    assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in params[2:])
    named = {p.name: p for p in params}
    assert named["provenance"].default is None and named["overwrite"].default is False
    assert inspect.signature(write).return_annotation in (int, "int")
