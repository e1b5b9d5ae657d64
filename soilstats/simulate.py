"""``python -m soilstats.simulate SPEC OUT --seed N``: simulate a campaign from a SPEC.

Command-line entry point only (see :mod:`soilstats.cli.simulate`); the library function is
:func:`soilstats.simulation.simulate`.
"""

from soilstats.cli.simulate import main

if __name__ == "__main__":
    raise SystemExit(main())
