"""Plain-text pieces every ``summary()`` shares, so that all reports read alike."""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["notes_block"]


def notes_block(notes: Iterable[object]) -> list[str]:
    """``Notes:`` and each note numbered ``[1] …`` (nothing when there are none; each note as
    its ``str``)."""
    notes = list(notes)
    if not notes:
        return []
    return ["Notes:", *(f"  [{i}] {note}" for i, note in enumerate(notes, 1))]
