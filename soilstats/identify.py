"""``python -m soilstats.identify``: Table-5-style identification of a campaign.

This module is the command-line entry point only (see :mod:`soilstats.cli.identify`); the
function ``soilstats.identify`` is the library's identification routine.
"""

from soilstats.cli.identify import main

if __name__ == "__main__":
    raise SystemExit(main())
