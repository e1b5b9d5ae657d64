"""What every result is written with: provenance, JSON-safe values, safe atomic files, notes.

The ground floor of soilstats' outputs: every layer that computes a result takes these from
here (a ``to_dict()`` is made JSON-safe, a ``summary()`` numbers its notes, a command writes
its files), and :mod:`soilstats.report` renders on top of them. Imports nothing of soilstats
but :mod:`soilstats._version` and :mod:`soilstats.errors`, and nothing heavy: pandas and numpy
load only when a writer is called.

==================  =====================================================================
``provenance``      version, campaign format and hash, command, seed, date
``files``           safe output paths, atomic writes (never through a link), JSON (no
                    NaN) and CSV with a provenance header (formula cells escaped)
``outset``          an output set as one unit: locked, staged, swapped in at the end
                    (``with output_set(folder):`` around any number of writes)
``text``            plain-text pieces every ``summary()`` shares
==================  =====================================================================
"""

from __future__ import annotations

from .files import json_safe, output_path, safe_stem, write_atomic, write_csv, write_json
from .outset import output_set
from .provenance import Provenance, source_date
from .text import notes_block

__all__ = [
    "Provenance",
    "json_safe",
    "notes_block",
    "output_path",
    "output_set",
    "safe_stem",
    "source_date",
    "write_atomic",
    "write_csv",
    "write_json",
]
