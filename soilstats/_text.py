"""Small text helpers shared by messages and reports."""

from __future__ import annotations

import re

__all__ = ["ascii_float", "natural_key", "non_ascii_note", "plural", "shown"]


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


def ascii_float(text: str) -> float:
    """``float(text)`` for ASCII text only; InputError (a ValueError, as ``float`` raises)
    otherwise.

    Python's ``float`` reads any Unicode decimal digit (``float("٣") == 3.0``, fullwidth
    ``"１"``): a number typed in another script would be taken silently, so it is refused.
    """
    if not str(text).isascii():
        from .errors import InputError  # not at the top: errors imports this module

        raise InputError(f"not an ASCII number: {text!r}")
    return float(text)


def non_ascii_note(text: str) -> str:
    """`` (numbers in ASCII digits only: '٣' is not one)`` for text with non-ASCII
    characters, else ``""``: the clause a refusal by :func:`ascii_float` adds to its message."""
    odd = "".join(dict.fromkeys(c for c in str(text) if not c.isascii()))
    return f" (numbers in ASCII digits only: {odd[:8]!r} is not one)" if odd else ""
