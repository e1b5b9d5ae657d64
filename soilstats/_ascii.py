"""Numbers read from text in ASCII digits only (issue #44).

Python's ``float`` reads any Unicode decimal digit (``float("٣") == 3.0``, fullwidth
``"１"``): a number typed in another script would be taken silently, so the text parsers of
options (``--prior``) read numbers through :func:`ascii_float`.
"""

from __future__ import annotations

from .errors import InputError

__all__ = ["ascii_float", "non_ascii_note"]


def ascii_float(text: str) -> float:
    """``float(text)`` for ASCII text only; InputError (a ValueError, as ``float`` raises)
    otherwise."""
    if not str(text).isascii():
        raise InputError(f"not an ASCII number: {text!r}")
    return float(text)


def non_ascii_note(text: str) -> str:
    """`` (numbers in ASCII digits only: '٣' is not one)`` for text with non-ASCII
    characters, else ``""``: the clause a refusal by :func:`ascii_float` adds to its message."""
    odd = "".join(dict.fromkeys(c for c in str(text) if not c.isascii()))
    return f" (numbers in ASCII digits only: {odd[:8]!r} is not one)" if odd else ""
