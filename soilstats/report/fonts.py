"""The fonts of report figures: Typst typesets a figure's SVG text with matplotlib's own fonts
only (never the system's: the same bytes on any machine)."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["figure_fonts", "shipped_fonts_only"]


def figure_fonts() -> list[str]:
    """The folder of the fonts matplotlib ships (DejaVu, STIX, Computer Modern): the fonts a
    figure's SVG text names, given to Typst (never the system's fonts: the same bytes on any
    machine)."""
    import matplotlib as mpl  # deferred: matplotlib

    return [os.path.join(mpl.get_data_path(), "fonts", "ttf")]


def shipped_fonts_only(fig: Figure) -> None:
    """Text whose font is not one matplotlib ships (a user's matplotlibrc or theme naming a
    system font) is set in DejaVu Sans: Typst sees only :func:`figure_fonts`, and a font it
    cannot find would be drawn in a substitute with other metrics than the layout's."""
    from matplotlib import font_manager  # deferred: matplotlib
    from matplotlib.text import Text  # deferred: matplotlib

    shipped = os.path.realpath(figure_fonts()[0])
    for text in fig.findobj(Text):
        try:
            found = str(font_manager.findfont(text.get_fontproperties(), fallback_to_default=False))
        except ValueError:  # no font of that family at all: matplotlib laid it out in DejaVu
            found = ""
        if not os.path.realpath(found).startswith(shipped):
            text.set_fontfamily("DejaVu Sans")
