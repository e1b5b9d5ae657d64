"""``python -m soilstats.study NAME``: run a setup-effect study (see soilstats.cli.study)."""

from soilstats.cli.study import main

if __name__ == "__main__":
    raise SystemExit(main())
