"""ArviZ imported once, without its import-time notice.

ArviZ 0.23 emits a ``FutureWarning`` announcing its 1.x refactor at import (at most once a
day, tracked by a stamp file).  It says nothing about our use; we support the 0.x API only
(``arviz>=0.17,<0.24`` in pyproject), so that one message is filtered here, narrowly, by
category and text — every other warning of ArviZ still reaches the user.
"""

from __future__ import annotations

import warnings

with warnings.catch_warnings():
    warnings.filterwarnings(
        "ignore", message=r"\s*ArviZ is undergoing a major refactor", category=FutureWarning
    )
    import arviz as az

__all__ = ["az"]
