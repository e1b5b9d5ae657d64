"""``python -m soilstats.study NAME``: the same as ``soilstats study NAME``."""

from soilstats.cli.main import run_subcommand

if __name__ == "__main__":
    raise SystemExit(run_subcommand("study"))
