"""The kinds of Bevameter test and of soil model: words every layer shares, in one place.

Imports nothing, so the campaign format (:mod:`soilstats.campaign.schema`), the model records
(:mod:`soilstats.models.base`), the simulator and the command line's parser all take them
from here without loading one another.
"""

from __future__ import annotations

__all__ = ["MODEL_KINDS", "TEST_KINDS"]

#: Values of a test's ``kind`` in a campaign's test log: a plate-sinkage test or a shear-ring
#: test (the samples of a test of kind K are in the sample file K; docs/campaign-format.md).
TEST_KINDS: tuple[str, ...] = ("sinkage", "shear")

#: What a soil model describes (``Model.kind``): a sinkage (plate) test, the shear-ring tests
#: of a campaign, or one shear test at one normal pressure (the per-test fit).
MODEL_KINDS: tuple[str, ...] = (*TEST_KINDS, "shear-test")
