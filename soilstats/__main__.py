"""``python -m soilstats ...``: the same as the ``soilstats`` command."""

from soilstats.cli.main import main

if __name__ == "__main__":
    raise SystemExit(main(prog="python -m soilstats"))
