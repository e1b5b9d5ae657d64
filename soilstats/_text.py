"""Small text helpers shared by messages and reports."""

from __future__ import annotations

__all__ = ["plural"]


def plural(n: int, word: str, many: str | None = None) -> str:
    """``"1 test"``, ``"3 tests"``: a count with its noun in the right number (``many``
    for an irregular plural)."""
    return f"{n} {word}" if n == 1 else f"{n} {many or word + 's'}"
