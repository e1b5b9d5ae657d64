"""Provenance of every output: which soilstats, which data, which command, which seed.

Every JSON, CSV and PDF that soilstats writes carries a :class:`Provenance`, so a number in a
report can be traced back to the exact input and reproduced. Outputs are reproducible byte for
byte: nothing here reads the clock unless ``SOURCE_DATE_EPOCH`` is set (the reproducible-builds
convention), in which case that time is recorded as ``created``.
"""

from __future__ import annotations

import datetime as _dt
import os
import shlex
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Protocol

from .._version import FORMAT_VERSION, __version__
from ..errors import InputError

__all__ = ["Provenance", "Source", "source_date"]


class Source(Protocol):
    """What :meth:`Provenance.of` reads of its input: a :class:`soilstats.campaign.Campaign`
    (its ``source`` and the digest of its content, ``Campaign.sha256()``)."""

    @property
    def source(self) -> str: ...

    def sha256(self) -> str: ...


def source_date() -> str | None:
    """ISO time of ``SOURCE_DATE_EPOCH`` (UTC), or None when it is not set."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    if not epoch:
        return None
    try:
        seconds = int(epoch)
    except ValueError:
        raise InputError(
            f"SOURCE_DATE_EPOCH must be whole seconds since 1970-01-01, got {epoch!r}"
        ) from None
    return _dt.datetime.fromtimestamp(seconds, _dt.UTC).isoformat(timespec="seconds")


@dataclass(frozen=True)
class Provenance:
    """Where an output came from.

    Attributes
    ----------
    soilstats_version : str
        ``soilstats.__version__`` that wrote the output.
    campaign_format : str
        Version of the campaign format of the input (``docs/campaign-format.md``).
    campaign : str
        The input campaign's source (folder, ``bundled:<name>`` or ``<memory>``).
    campaign_sha256 : str
        ``Campaign.sha256()`` (:func:`soilstats.campaign.digest.campaign_sha256`) of the
        input as the command received it: loaded, after ``--select``, before screening and
        fitting windows (the
        command line records those and every other restriction, such as identify's
        ``--series``), so every command on the same data and selection names one digest.
    command : str
        The command line (``soilstats ...``), or ``"python API"`` for library calls.
    seed : int or None
        Seed of every random step (None: the output drew no random numbers).
    created : str or None
        ISO time from ``SOURCE_DATE_EPOCH``; None otherwise (no clock is read).
    method : str
        The paper the method follows (Apfelbeck et al. 2011).
    """

    soilstats_version: str
    campaign_format: str
    campaign: str
    campaign_sha256: str
    command: str
    seed: int | None
    created: str | None = None
    method: str = (
        'M. Apfelbeck, S. Kuß, B. Rebele, B. Schäfer, "A systematic approach to reliably '
        'characterize soils based on Bevameter testing", J. Terramechanics 48(5), 360-371, 2011'
    )

    @classmethod
    def of(
        cls,
        campaign: Source | None,
        *,
        argv: Sequence[str] | None = None,
        seed: int | None = None,
    ) -> Provenance:
        """Provenance of an output computed from ``campaign`` (None: no campaign input).

        ``argv`` is the command line after the program name (``["study", "velocity"]``);
        None records a library call.
        """
        return cls(
            soilstats_version=__version__,
            campaign_format=FORMAT_VERSION,
            campaign="" if campaign is None else campaign.source,
            campaign_sha256="" if campaign is None else campaign.sha256(),
            command="python API" if argv is None else shlex.join(["soilstats", *argv]),
            seed=seed,
            created=source_date(),
        )

    def to_dict(self) -> dict:
        """The fields as a JSON-ready dict (``created`` left out when None)."""
        out = asdict(self)
        if out["created"] is None:
            del out["created"]
        return out

    def lines(self) -> list[str]:
        """``key: value`` lines for a text page, a CSV comment header or a summary."""
        return [f"{key}: {'' if value is None else value}" for key, value in self.to_dict().items()]

    def pdf_metadata(self, title: str) -> dict:
        """The PDF document-information dictionary (no creation date unless requested)."""
        created = _dt.datetime.fromisoformat(self.created) if self.created is not None else None
        return {
            "Title": title,
            "Creator": f"soilstats {self.soilstats_version}",
            "Producer": f"soilstats {self.soilstats_version}",
            "Subject": f"{self.campaign} sha256:{self.campaign_sha256}",
            "Keywords": f"command: {self.command}; seed: {self.seed}; "
            f"campaign format v{self.campaign_format}",
            "CreationDate": created,
            "ModDate": created,
        }
