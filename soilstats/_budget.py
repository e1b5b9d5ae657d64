"""The memory budget: a check before any allocation whose size a user's number sets.

``posterior --draws 1000000000`` once asked numpy for 15 GiB and ended in a traceback; a
100 M-row Parquet file or a gzip bomb ran Arrow out of memory.  Each such place estimates
its bytes first and calls :func:`check_budget`, which refuses, naming the option or file and
the size, before anything is allocated.

The budget is :data:`MEMORY_BUDGET_BYTES` (4 GiB), or ``SOILSTATS_MEMORY_BUDGET_GB`` from the
environment for a larger machine.
"""

from __future__ import annotations

import os

from .errors import InputError

__all__ = ["MEMORY_BUDGET_BYTES", "check_budget", "memory_budget"]

#: Default budget of one allocation sized by user input [bytes].
MEMORY_BUDGET_BYTES = 4 * 2**30


def memory_budget() -> int:
    """The budget in bytes: ``SOILSTATS_MEMORY_BUDGET_GB`` (GiB, > 0) or the default."""
    text = os.environ.get("SOILSTATS_MEMORY_BUDGET_GB", "").strip()
    if not text:
        return MEMORY_BUDGET_BYTES
    try:
        gib = float(text)
    except ValueError:
        gib = float("nan")
    if not (0 < gib < 1e6):
        raise InputError(
            f"SOILSTATS_MEMORY_BUDGET_GB must be a number of GiB in (0, 1e6), got {text!r}"
        )
    return int(gib * 2**30)


def check_budget(what: str, nbytes: float, fix: str) -> None:
    """Refuse ``what`` (e.g. ``"--draws 1000000000"``) when it needs more than the budget.

    ``nbytes`` is the estimated size of the allocation; ``fix`` says what to do instead.
    """
    budget = memory_budget()
    if not nbytes <= budget:
        raise InputError(
            f"{what} needs about {nbytes / 2**30:.3g} GiB of memory, beyond the budget of "
            f"{budget / 2**30:.3g} GiB (SOILSTATS_MEMORY_BUDGET_GB); {fix}"
        )
