"""Simulated Bevameter campaigns with known truth (GitHub issue #3).

A declarative SPEC (TOML; format in ``docs/simulator.md``) names soils and their parameters,
test series, preparation scatter, noise and planted effects; :func:`simulate` turns it into a
:class:`~soilstats.campaign.Campaign` in the campaign format, with the truth beside it.

>>> from soilstats.simulation import simulate
>>> sim = simulate("soilstats/data/simulated-paper/spec.toml", seed=2026)  # doctest: +SKIP
>>> sim.campaign, sim.test_truth.head()                                     # doctest: +SKIP
>>> sim.save("my-campaign")                                                 # doctest: +SKIP

Command line: ``python -m soilstats.simulate SPEC OUT --seed N``.
"""

from __future__ import annotations

from .simulate import SimulatedCampaign, simulate
from .spec import Spec, SpecError, load_spec, parse_spec

__all__ = ["SimulatedCampaign", "Spec", "SpecError", "load_spec", "parse_spec", "simulate"]
