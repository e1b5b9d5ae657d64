"""Small text helpers shared by messages and reports."""

from __future__ import annotations

import re

__all__ = ["natural_key", "plural", "shown"]


def plural(n: int, word: str, many: str | None = None) -> str:
    """``"1 test"``, ``"3 tests"``: a count with its noun in the right number (``many``
    for an irregular plural)."""
    return f"{n} {word}" if n == 1 else f"{n} {many or word + 's'}"


def shown(value: object, width: int = 60) -> str:
    """``repr(value)``, cut to about ``width`` characters for a one-line message.

    A message names the cell it refuses; a hostile cell (a 140 KiB test_id, an unclosed
    quote that swallowed the rest of a file) must not turn that one line into a page.
    ``repr`` also shows control characters (``'c1\\x00'``) that would otherwise be invisible.
    """
    text = repr(value)
    if len(text) <= width:
        return text
    return f"{text[: width - 1]}…' ({len(str(value))} characters)"


def natural_key(value: object) -> tuple:
    """Sort key that orders numbers by value and text by its digit runs as numbers."""
    if isinstance(value, int | float):  # bool included
        return (0, float(value), "")
    text = str(value)
    try:
        return (0, float(text), "")
    except ValueError:
        parts = re.split(r"(\d+(?:\.\d+)?)", text)
        return (
            1,
            0.0,
            tuple((0, float(p), "") if i % 2 else (1, 0.0, p) for i, p in enumerate(parts)),
        )
