"""``python -m soilstats.discover CAMPAIGN_DIR [--json] [--out DIR]``: what the model gets wrong.

This module is the command-line entry point only (see :mod:`soilstats.cli.discover`); the
function ``soilstats.discover`` is the library routine.
"""

from soilstats.cli.discover import main

if __name__ == "__main__":
    raise SystemExit(main())
