"""``python -m soilstats.posterior``: posterior draws of a campaign's soil parameters.

This module is the command-line entry point only (see :mod:`soilstats.cli.posterior`); the
library lives in :mod:`soilstats.bayes`.
"""

from soilstats.cli.posterior import main

if __name__ == "__main__":
    raise SystemExit(main())
