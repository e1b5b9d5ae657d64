"""Small text helpers shared by messages and reports."""

from __future__ import annotations

__all__ = ["plural", "shown"]


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
