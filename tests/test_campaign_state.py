"""A campaign holds the campaign format's data and nothing of the floors above it
(docs/conventions.md, "Layers"; issue #38): its fields are precisely typed with types of the
campaign floor or below, screening's report travels on a ``ScreenedCampaign`` (the quality
floor's own class), and the old spellings still work for one release, with a FutureWarning.
"""

from __future__ import annotations

import dataclasses
import pickle
import types
import typing

import pytest
from test_layers import floors

from soilstats.campaign import Campaign, load_campaign
from soilstats.campaign.window import AppliedWindow, FitWindow
from soilstats.quality import QualityReport, ScreenedCampaign, screen, screened

#: Modules a field's type may come from besides soilstats' own (the format's tables).
OUTSIDE = {"builtins", "collections", "typing", "pandas", "numpy"}


def _parts(hint) -> list:
    """Every type a field annotation names: ``Mapping[str, str] | None`` gives Mapping,
    str, str and NoneType."""
    args = typing.get_args(hint)
    origin = typing.get_origin(hint)
    named = [] if origin in (None, typing.Union, types.UnionType) else [origin]
    if not args:
        return [hint]
    return named + [p for a in args for p in _parts(a)]


def test_every_field_of_campaign_is_precisely_typed_and_of_the_campaign_floor_or_below():
    listed = floors()
    hints = typing.get_type_hints(Campaign)
    names = [f.name for f in dataclasses.fields(Campaign)]
    # A new field is campaign-format data (or a campaign-floor type): add it here once its
    # type passes the checks below.
    assert names == ["tests", "sinkage", "shear", "source", "skipped", "window", "files"]
    for name in names:
        for part in _parts(hints[name]):
            assert part is not typing.Any and part is not object, f"Campaign.{name}: {part}"
            module = getattr(part, "__module__", "")
            top = module.split(".")[0]
            if top == "soilstats":
                package = module.split(".")[1]
                assert listed[package] <= listed["campaign"], (
                    f"Campaign.{name} is a {part.__qualname__} of floor {listed[package]} "
                    f"({package}): a campaign holds no upper-layer state"
                )
            else:
                assert top in OUTSIDE or part is type(None), f"Campaign.{name}: {part}"
    assert hints["window"] == AppliedWindow | None


def test_screening_returns_a_screened_campaign_that_selections_keep():
    campaign = load_campaign("cullinan-sand")
    report = screen(campaign)
    cleaned = report.campaign
    assert type(cleaned) is ScreenedCampaign and isinstance(cleaned, Campaign)
    assert isinstance(cleaned.report, QualityReport) and cleaned.report.mode == "clean"
    assert cleaned.report.campaign is None  # the report on the campaign does not loop back
    ids = list(cleaned.tests["test_id"])
    window = FitWindow.of(z_max=0.02)
    for derived in (
        cleaned.select(test_id=ids[:3]),
        cleaned.partition([ids[:3], ids[3:5]])[1],
        cleaned.windowed(window),
    ):
        assert type(derived) is ScreenedCampaign and derived.report is cleaned.report
    assert cleaned.windowed(window).window is not None
    assert cleaned.windowed(None) is cleaned
    # Analyses take a screened campaign as it is, and screen a plain one once per mode.
    assert screened(cleaned) is cleaned
    assert type(screened(campaign)) is ScreenedCampaign
    assert screened(campaign, "flag").report.mode == "flag"
    back = pickle.loads(pickle.dumps(cleaned.windowed(window)))  # as sent to workers
    assert type(back) is ScreenedCampaign and back.report.mode == "clean"
    assert back.window is not None and back.window.window == window


def test_a_plain_campaign_holds_no_screening_state():
    campaign = load_campaign("cullinan-sand")
    assert not isinstance(campaign, ScreenedCampaign)
    with pytest.raises(TypeError, match="quality"):
        dataclasses.replace(campaign, quality=None)
    # ScreenedCampaign.of pairs the campaign's own tables (the same objects) with a report.
    off = ScreenedCampaign.of(campaign, screen(campaign, "off"))
    for name in ("tests", "sinkage", "shear", "source", "skipped", "window", "files"):
        assert getattr(off, name) is getattr(campaign, name)


def test_the_old_spellings_warn_and_still_answer():
    campaign = load_campaign("cullinan-sand")
    report = screen(campaign)
    with pytest.warns(FutureWarning, match=r"report\.campaign.*\.report"):
        assert campaign.quality is None
    with pytest.warns(FutureWarning, match=r"\.report"):
        assert report.campaign.quality is report.campaign.report
    from soilstats.campaign.window import windowed

    window = FitWindow.of(z_max=0.02)
    with pytest.warns(FutureWarning, match=r"campaign\.windowed\(window\)"):
        old = windowed(report.campaign, window)
    new = report.campaign.windowed(window)
    assert type(old) is ScreenedCampaign and old.sinkage.equals(new.sinkage)
    assert old.window.per_test.equals(new.window.per_test)
