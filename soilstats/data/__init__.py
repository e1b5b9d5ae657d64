"""Campaigns bundled with soilstats, one folder each (``soilstats/data/<name>/``).

A bundled campaign is any sub-folder holding a ``tests.csv`` or ``tests.parquet``; adding a
folder is enough to add one. Load them with ``soilstats.campaign.load_campaign("<name>")``;
each folder's ``README.md`` names the source and licence of the data.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["DATA_DIR", "bundled_names", "bundled_path"]

#: Folder of the bundled campaigns.
DATA_DIR: Path = Path(__file__).resolve().parent


def bundled_names() -> list[str]:
    """Return the names of the bundled campaigns, sorted.

    Returns
    -------
    list of str
        Folder names under :data:`DATA_DIR` that hold a campaign log.
    """
    return sorted(
        p.name
        for p in DATA_DIR.iterdir()
        if p.is_dir() and ((p / "tests.csv").is_file() or (p / "tests.parquet").is_file())
    )


def bundled_path(name: str) -> Path | None:
    """Return the folder of bundled campaign ``name``, or None if there is no such campaign."""
    return DATA_DIR / name if name in bundled_names() else None
