"""ArviZ imported once, without its import-time notice.

ArviZ 0.23 emits a ``FutureWarning`` announcing its 1.x refactor at import (at most once a
day, tracked by a stamp file).  It says nothing about our use; we support the 0.x API only
(``arviz>=0.17,<0.24`` in pyproject), so that one message is filtered here, narrowly, by
category and text — every other warning of ArviZ still reaches the user.
"""

from __future__ import annotations

import datetime
import os
import tempfile
import warnings
from pathlib import Path


def _stamp_daily_notice() -> None:
    """Write ArviZ's once-a-day stamp (today's date) atomically, before ArviZ does.

    ArviZ 0.23 writes that stamp through one fixed temporary name, so several processes that
    import it at once on a new day (pytest-xdist workers, joblib workers) race: one renames
    the file away under the other, and ``import arviz`` fails with FileNotFoundError. With
    today's date already there ArviZ writes nothing; a unique temporary name per process
    makes our own write race-free.
    """
    try:
        from platformdirs import user_cache_dir  # deferred: platformdirs (optional)

        folder = Path(user_cache_dir("arviz", "arviz"))
        stamp = folder / "daily_warning"
        today = datetime.date.today().isoformat()
        if stamp.is_file() and stamp.read_text().strip() == today:
            return
        folder.mkdir(parents=True, exist_ok=True)
        handle, tmp = tempfile.mkstemp(dir=folder, prefix="daily_warning.", suffix=".tmp")
        with os.fdopen(handle, "w") as out:
            out.write(today)
        os.replace(tmp, stamp)
    except (ImportError, OSError):  # no platformdirs or a read-only cache: ArviZ's own path
        return


_stamp_daily_notice()
with warnings.catch_warnings():
    warnings.filterwarnings(
        "ignore", message=r"\s*ArviZ is undergoing a major refactor", category=FutureWarning
    )
    import arviz as az

__all__ = ["az"]
