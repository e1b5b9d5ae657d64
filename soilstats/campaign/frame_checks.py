"""What a table given as a DataFrame (:meth:`Campaign.from_frames
<soilstats.campaign.Campaign.from_frames>`) could never hold, refused before validation:
column names that are not unique plain text, and complex numbers (issue #44)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..errors import CampaignError

__all__ = ["check_frame"]


def check_frame(frame: pd.DataFrame, name: str) -> None:
    """Refuse what a table read from a file could never hold: columns that are not unique
    plain names, and complex numbers (casting drops the imaginary part silently)."""
    if isinstance(frame.columns, pd.MultiIndex) or not all(
        isinstance(c, str) for c in frame.columns
    ):
        bad = next(c for c in frame.columns if not isinstance(c, str))
        raise CampaignError(
            f"column names must be text, got {bad!r} — flatten or rename the columns",
            file=name,
        )
    dup = sorted({c for c in frame.columns if list(frame.columns).count(c) > 1})
    if dup:
        raise CampaignError(
            f"column(s) {dup} appear more than once; every column name must be unique",
            file=name,
            column=dup[0],
        )
    for col in frame.columns:
        values = frame[col]
        if np.iscomplexobj(values.to_numpy()):
            cells = np.ones(len(values), dtype=bool)
        elif values.dtype == object:
            cells = np.array([isinstance(v, complex | np.complexfloating) for v in values])
        else:
            continue
        if cells.any():
            row = int(np.flatnonzero(cells)[0]) + 1
            raise CampaignError(
                f"holds complex numbers (e.g. {complex(values.iloc[row - 1])}); a measured "
                "quantity is real — give the real part explicitly if that is what was meant",
                file=name,
                column=col,
                row=row,
            )
