"""The report engine: a typeset PDF document built from prose, tables, equations and figures.

Every PDF soilstats writes is a :class:`Document` rendered by Typst (the ``typst`` Python
package: a typesetting compiler that ships as one offline wheel, with its own fonts). Typst
gives what hand-laid matplotlib pages could not: text that wraps and never runs off the page,
tables that continue on the next page with their header repeated, typeset mathematics for the
paper's equations, numbered pages, one page size, embedded (subset TrueType/OpenType) fonts
and searchable text. matplotlib/seaborn still draw the figures; they enter as SVG (vector,
text as paths) so what is plotted is exactly what is printed.

Text from results (test names, notes, messages) always enters as Typst *string literals*, so
no character in data can be read as markup; only this package writes markup.

Outputs are reproducible byte for byte: no system fonts are read (the fonts embedded in the
compiler are used on every machine), no clock is read (``SOURCE_DATE_EPOCH`` sets the
document date, as for every other output), and figure ids are salted with a constant.
"""

from __future__ import annotations

import datetime as _dt
import io
import re
import subprocess
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from math import isfinite, isnan
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import InputError
from ..outputs.files import write_atomic
from .fonts import figure_fonts, shipped_fonts_only

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure
    from matplotlib.text import Text
    from matplotlib.typing import RcKeyType

    from ..outputs.provenance import Provenance

__all__ = ["Document", "Markup", "esc", "math", "strong"]

PAGE = "a4"
BODY_PT = 10
TABLE_PT = 8
SMALL_PT = 8  # appendix tables and lists: the reader's last stop, and never smaller
#: matplotlib rc of the report figures (``rc_context(FIGURE_STYLE)``): 9 pt text and titles,
#: 8 pt ticks and legends at print width, a step below the body, and no top or right spine.
FIGURE_STYLE: dict[RcKeyType, Any] = {
    "font.size": 9,
    "axes.titlesize": 9,
    "axes.labelsize": 9,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "legend.fontsize": 8,
    "figure.titlesize": 9,
    "axes.spines.top": False,
    "axes.spines.right": False,
}
#: FIGURE_STYLE for a grid of small panels, several to a row (discover's findings): 8 pt
#: throughout, the smallest a report prints (issue #47, item 5).
GRID_STYLE: dict[RcKeyType, Any] = {
    **FIGURE_STYLE,
    "font.size": 8,
    "axes.titlesize": 8,
    "axes.labelsize": 8,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "legend.fontsize": 8,
    "figure.titlesize": 8,
}
# Long unbroken tokens (test ids, file paths, column names) get break opportunities after
# these characters, so that a narrow table cell wraps them instead of overflowing the page.
_BREAK_AFTER = re.compile(r"([_/.:=,;|\\-])(?=\S)")
_LONG_TOKEN = 18


@dataclass(frozen=True)
class Markup:
    """Typst markup written by this package (never built from data without :func:`esc`)."""

    text: str

    def __add__(self, other: Markup | str) -> Markup:
        return Markup(self.text + _markup(other).text)

    def __radd__(self, other: str) -> Markup:
        return Markup(_markup(other).text + self.text)


def _breakable(text: str) -> str:
    """``text`` with zero-width break opportunities inside tokens longer than 18 characters."""
    if len(text) <= _LONG_TOKEN:
        return text
    return " ".join(
        _BREAK_AFTER.sub("\\1\u200b", word) if len(word) > _LONG_TOKEN else word
        for word in text.split(" ")
    )


def esc(text: object, *, breakable: bool = False) -> Markup:
    """Any value as literal text in a Typst document (a string literal: no markup applies).

    ``breakable`` adds break opportunities inside long tokens (for narrow table cells).
    """
    s = _breakable(str(text)) if breakable else str(text)
    s = s.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n").replace("\r", "")
    return Markup(f'#"{s}"')


def strong(text: object) -> Markup:
    """Bold literal text."""
    return Markup(f"#strong({esc(text).text[1:]})")


def math(expression: str) -> Markup:
    """Inline Typst mathematics, e.g. ``math("k_c")`` (written by this package only)."""
    return Markup(f"${expression}$")


def _markup(part: Markup | str | object) -> Markup:
    return part if isinstance(part, Markup) else esc(part)


def _join(parts: Iterable[Markup | str | object]) -> str:
    return "".join(_markup(p).text for p in parts)


def _typst_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", " ") + '"'


class Document:
    """A report under construction: add blocks in reading order, then :meth:`render`.

    Parameters
    ----------
    title : str
        Title on page 1 and in the PDF metadata.
    subtitle : str, optional
        One line under the title (e.g. the command and the data set).
    provenance : Provenance, optional
        Written to the PDF metadata and, by :meth:`provenance_section`, on the last page.

    Examples
    --------
    >>> doc = Document("Velocity study")
    >>> doc.heading("Conclusion")
    >>> doc.paragraph("soil02 is ", strong("stiffer"), " at 5 mm/s than at 50 mm/s.")
    >>> doc.render("velocity.pdf")  # doctest: +SKIP
    """

    def __init__(self, title: str, *, subtitle: str = "", provenance: Provenance | None = None):
        self.title = title
        self.provenance = provenance
        self._blocks: list[str] = []
        self._images: dict[str, bytes] = {}
        self._block(f'#align(center, text(17pt, weight: "bold", {_typst_string(title)}))')
        if subtitle:
            self._block(f"#align(center, text(10pt, {_typst_string(subtitle)}))")

    # -- blocks -----------------------------------------------------------------------------
    def _block(self, markup: str) -> None:
        self._blocks.append(markup)

    def heading(self, text: str, level: int = 1) -> None:
        """A section heading (level 1) or subsection (level 2, 3)."""
        self._block(f"#heading(level: {int(level)}, {_typst_string(text)})")

    def paragraph(self, *parts: Markup | str | object) -> None:
        """One paragraph of literal text and :class:`Markup` pieces."""
        if parts:
            self._block(_join(parts))

    def note(self, *parts: Markup | str | object) -> None:
        """A small-print paragraph (caveats, definitions)."""
        self._block(f"#text(size: 8.5pt)[{_join(parts)}]")

    def bullets(self, items: Iterable[Markup | str | Sequence[Markup | str]]) -> None:
        """A bulleted list; an item is text, markup, or a sequence of both."""
        self._list(items, "-", "")

    def numbered(
        self, items: Iterable[Markup | str | Sequence[Markup | str]], *, small: bool = False
    ) -> None:
        """A numbered list ([1], [2], … as in the summaries); ``small`` in appendix print."""
        setup = '#set enum(numbering: "[1]")\n'
        if small:
            setup += f"#set text(size: {SMALL_PT}pt)\n"
        self._list(items, "+", setup)

    def _list(self, items: Iterable[object], marker: str, setup: str) -> None:
        lines = []
        for item in items:
            parts = item if isinstance(item, list | tuple) else (item,)
            lines.append(f"{marker} {_join(parts)}")
        if lines:
            self._block(f"#[{setup}" + "\n".join(lines) + "\n]")

    def equation(self, expression: str, tag: str = "") -> None:
        """A displayed equation in Typst math, with a tag such as ``"Eq. 7"`` at the right."""
        body = f"$ {expression} $"
        if tag:
            body = (
                f"#grid(columns: (1fr, auto), align: (center + horizon, right + horizon), "
                f"[{body}], [({tag})])"
            )
        self._block(body)

    def equations(self, rows: Iterable[tuple[str, str, str]], *, columns: int = 2) -> None:
        """Displayed equations side by side, ``columns`` to a row: each ``(what, expression,
        tag)`` as its description over the equation (Typst math) and its tag."""
        cells = [
            f"[{esc(what).text}\n#grid(columns: (1fr, auto), align: (center + horizon, "
            f"right + horizon), [$ {expression} $], [({tag})])]"
            for what, expression, tag in rows
        ]
        if cells:
            self._block(
                f"#grid(columns: {int(columns)}, column-gutter: 18pt, row-gutter: 10pt, "
                + ", ".join(cells)
                + ")"
            )

    def key_values(self, rows: Iterable[tuple[str, object]]) -> None:
        """A two-column list of labels and values (no rules), e.g. the provenance."""
        cells = []
        for key, value in rows:
            cells.append(f"[{strong(key).text}]")
            cells.append(f"[{esc('' if value is None else value).text}]")
        if cells:
            self._block(
                "#table(columns: (auto, 1fr), stroke: none, inset: 3pt, " + ", ".join(cells) + ")"
            )

    def table(
        self,
        frame: pd.DataFrame,
        *,
        caption: str = "",
        labels: dict[str, str | Markup] | None = None,
        formats: dict[str, str] | None = None,
        align_numbers: bool = True,
        small: bool = False,
        widths: Sequence[str] | None = None,
        sections: str | None = None,
    ) -> None:
        """A table of ``frame``: every row, every column, never clipped.

        Long tables continue on the next page with the header repeated; wide ones wrap their
        cells. ``labels`` renames columns for the reader (human names with units); ``formats``
        gives a format spec per column (default: 4 significant digits for floats); missing
        values print as an en dash. ``small`` sets it in appendix print (``SMALL_PT``, rows
        closer together);
        ``widths`` gives Typst column widths (``"auto"``, ``"1fr"``, ``"22%"``), one per column.
        ``sections`` names a column printed not as a column but as a row across the table
        wherever its value changes (``sinkage / soil01``, then that group's rows); ``widths``
        then omits it.
        """
        import pandas as pd  # deferred: pandas (a table)

        labels = labels or {}
        formats = formats or {}
        every = list(frame.columns)
        columns = [c for c in every if c != sections]
        if not columns:
            return
        numeric = {c: pd.api.types.is_numeric_dtype(frame[c]) for c in columns}
        head = ", ".join(f"[#strong[{_markup(labels.get(c, c)).text}]]" for c in columns)
        body = []
        current = object()
        for values in frame.itertuples(index=False, name=None):
            if sections is not None and values[every.index(sections)] != current:
                current = values[every.index(sections)]
                body.append(f"table.cell(colspan: {len(columns)})[{strong(current).text}]")
            row = [v for c, v in zip(every, values, strict=True) if c != sections]
            for c, value in zip(columns, row, strict=True):
                cell = esc(format_cell(value, formats.get(c)), breakable=True)
                body.append(f"[{cell.text}]")
        align = ", ".join("right" if numeric[c] and align_numbers else "left" for c in columns)
        inset = "(x: 3pt, y: 1.3pt)" if small else "3pt"  # appendix rows: closer together
        table = (
            f"#table(columns: {_columns(widths, len(columns))}, align: ({align},), "
            f"inset: {inset}, "
            "stroke: (x, y) => if y == 0 { (bottom: 0.6pt) } "
            "else { (bottom: 0.2pt + luma(200)) }, "
            f"table.header({head}), " + ", ".join(body) + ")"
        )
        size = f"#set text(size: {SMALL_PT if small else TABLE_PT}pt)"
        if small:
            size += "\n#set par(leading: 0.4em)"
        table = f"#[{size}\n{table}]"
        if caption:
            table = (
                f"#figure(kind: table, supplement: [Table], caption: {_typst_caption(caption)}, "
                f"{table[1:]})"
            )
        self._block(table)

    @contextmanager
    def columns(self, n: int = 2) -> Iterator[Document]:
        """Set the blocks added inside ``with doc.columns(2):`` in ``n`` columns (narrow
        tables side by side: a long one flows on into the next column)."""
        start = len(self._blocks)
        yield self
        inner = self._blocks[start:]
        del self._blocks[start:]
        if inner:
            self._block(f"#columns({int(n)}, gutter: 14pt)[\n" + "\n\n".join(inner) + "\n]")

    def figure(self, fig: Figure, caption: str, *, width: str = "100%") -> None:
        """A matplotlib figure (closed afterwards) as vector graphics with a numbered caption."""
        self.svg_figure(figure_svg(fig), caption, width=width)

    def svg_figure(self, svg: bytes, caption: str, *, width: str = "100%") -> None:
        """A figure already drawn as SVG (:func:`figure_svg`, e.g. in a worker process) with a
        numbered caption."""
        name = f"figure-{len(self._images) + 1}.svg"
        self._images[name] = svg
        self._block(f'#figure(image("{name}", width: {width}), caption: {_typst_caption(caption)})')

    def page_break(self) -> None:
        """Start the next block on a new page."""
        self._block("#pagebreak(weak: true)")

    def provenance_section(self, *, new_page: bool = True) -> None:
        """The last page: soilstats version, input hash, command, seed, method citation
        (``new_page=False``: the last section, on the page where the report ends)."""
        if self.provenance is None:
            return
        if new_page:
            self.page_break()
        self.heading("Provenance")
        self.paragraph(
            "Everything in this report follows from the input below with the command and seed "
            "shown; the same inputs give a byte-identical file."
        )
        self.key_values(
            (key.replace("_", " "), value) for key, value in self.provenance.to_dict().items()
        )

    # -- output -----------------------------------------------------------------------------
    def source(self) -> str:
        """The complete Typst source (for debugging a layout)."""
        return _preamble(self.title, self.provenance) + "\n\n".join(self._blocks) + "\n"

    def render(self, path: str | Path) -> int:
        """Typeset the document into the PDF ``path``; return its number of pages.

        Raises
        ------
        RuntimeError
            If Typst rejects the document (a bug in the report, never the user's data:
            data enters only as string literals); the message carries Typst's diagnostic.
        """
        import typst  # deferred: typst (a PDF)

        path = Path(path)
        with tempfile.TemporaryDirectory(prefix="soilstats-report-") as tmp:
            root = Path(tmp)
            for name, data in self._images.items():
                (root / name).write_bytes(data)
            main = root / "report.typ"
            main.write_text(self.source(), encoding="utf-8")
            try:
                pdf = typst.compile(
                    str(main), root=str(root), font_paths=figure_fonts(), ignore_system_fonts=True
                )
            except Exception as exc:  # typst raises its own TypstError type
                raise RuntimeError(f"the report {path.name} could not be typeset: {exc}") from exc
        write_atomic(path, pdf)  # never half a PDF, never through a link
        return page_count(pdf)


def format_cell(value: object, spec: str | None = None) -> str:
    """One table cell as text: ``spec`` if given, floats to 4 significant digits, NaN as –."""
    import numpy as np  # deferred: numpy (a table cell)

    if value is None:
        return "–"
    if isinstance(value, float | np.floating):
        if not isfinite(value):
            return "–" if isnan(value) else str(value)
        return format(value, spec or ".4g")
    if isinstance(value, bool | np.bool_):
        return "yes" if value else "no"
    if spec and isinstance(value, int | np.integer):
        return format(value, spec)
    try:
        import pandas as pd  # deferred: pandas (a table cell)

        if pd.isna(value):  # type: ignore[call-overload]  # pandas-stubs: isna of any object is valid
            return "–"
    except (TypeError, ValueError):
        pass
    return str(value)


def render_page(pdf: str | Path, stem: str | Path, *, page: int = 1, dpi: int = 70) -> Path:
    """Render one page of ``pdf`` to ``stem``.png with poppler's ``pdftoppm``; return the path.

    Raises FileNotFoundError when pdftoppm (Debian: poppler-utils) is not installed and
    subprocess.CalledProcessError when it cannot render the page.
    """
    command = ["pdftoppm", "-r", str(dpi), "-png", "-f", str(page), "-l", str(page)]
    subprocess.run([*command, "-singlefile", str(pdf), str(stem)], check=True, capture_output=True)
    return Path(f"{stem}.png")


def page_count(pdf: bytes) -> int:
    """Pages of a PDF Typst wrote (its page objects are uncompressed: ``/Type /Page``)."""
    return len(re.findall(rb"/Type\s*/Page(?![a-zA-Z])", pdf))


#: Attribute marking a figure text of soilstats' own written in mathtext (:func:`math_text`).
_MATH = "_soilstats_math"


def math_text(text: Text) -> Text:
    """Mark ``text`` (a label soilstats wrote, e.g. ``$k_c$ (kN/m$^{n+1}$)``) as mathtext;
    every other text of a report figure is printed as written (:func:`figure_svg`)."""
    setattr(text, _MATH, True)
    return text


def plain_texts(fig: Figure) -> None:
    """Print every text of ``fig`` not marked by :func:`math_text` as written: data labels
    (soil names, levels, test ids) never go through mathtext, so a ``$`` is a ``$`` and a
    ``$x^{`` in a soil name cannot stop a report with a parser error."""
    from matplotlib.text import Text  # deferred: matplotlib

    for text in fig.findobj(Text):
        if not getattr(text, _MATH, False):
            text.set_parse_math(False)


def tight_layout(fig: Figure) -> None:
    """``fig.tight_layout()`` with every data label plain (:func:`plain_texts`): laying out
    measures the texts, and measuring parses them."""
    import matplotlib as mpl  # deferred: matplotlib

    plain_texts(fig)
    plain_log_ticks(fig)
    with mpl.rc_context({"text.parse_math": False}):
        fig.tight_layout()


_SUPERSCRIPT = str.maketrans("0123456789-−", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻⁻")


def _plain_math(label: str) -> str:
    """A log axis' mathtext tick label as plain text: ``$\\mathdefault{10^{-1}}$`` -> 10⁻¹,
    ``2\\times10^{1}`` -> 2×10¹ (the figure's text is printed as written: :func:`plain_texts`)."""
    if not label.startswith("$"):
        return label
    text = label.strip("$").replace("\\mathdefault", "").replace("\\times", "×")
    text = re.sub(r"\^\{([^}]*)\}", lambda m: m.group(1).translate(_SUPERSCRIPT), text)
    return text.replace("{", "").replace("}", "").replace("\\,", "").replace("-", "−")


def plain_log_ticks(fig: Figure) -> None:
    """Every log axis of ``fig`` labelled in plain text (10⁻¹, 10², 2×10¹): matplotlib writes
    its log tick labels in mathtext, which the report's figures print as written."""
    from matplotlib.ticker import Formatter, LogFormatter  # deferred: matplotlib

    class PlainLog(Formatter):
        """The log formatter's own labels (and its choice of minor ticks to label), plain."""

        def __init__(self, inner: LogFormatter) -> None:
            self.inner = inner

        def set_axis(self, axis: Any) -> None:
            super().set_axis(axis)
            self.inner.set_axis(axis)

        def set_locs(self, locs: Any) -> None:
            self.inner.set_locs(locs)

        def __call__(self, x: float, pos: int | None = None) -> str:
            return _plain_math(self.inner(x, pos))

    for ax in fig.get_axes():
        for axis in (ax.xaxis, ax.yaxis):
            for get, put in (
                (axis.get_major_formatter, axis.set_major_formatter),
                (axis.get_minor_formatter, axis.set_minor_formatter),
            ):
                old = get()
                if isinstance(old, LogFormatter):
                    put(PlainLog(old))


def figure_svg(fig: Figure) -> bytes:
    """A matplotlib figure as the SVG a report embeds (a fixed hash salt and no date: the same
    figure gives the same bytes, in any process); the figure is closed. Data labels are
    printed as written (:func:`plain_texts`). Its text stays text (``svg.fonttype`` none),
    set by Typst in matplotlib's own DejaVu fonts (:func:`figure_fonts`): the PDF carries it
    as real text, so a reader can search it and a test can read its sizes and boxes
    (issue #47, item 5), where paths hid both."""
    import matplotlib as mpl  # deferred: matplotlib

    plain_texts(fig)
    plain_log_ticks(fig)
    shipped_fonts_only(fig)
    buffer = io.BytesIO()
    # Tick labels made while drawing (categorical axes: the data's levels) are plain too.
    style: dict[RcKeyType, Any] = {
        "svg.hashsalt": "soilstats",
        "svg.fonttype": "none",
        "text.parse_math": False,
    }
    with mpl.rc_context(style):
        fig.savefig(buffer, format="svg", metadata={"Date": None})
    _close(fig)
    return buffer.getvalue()


def _close(fig: Figure) -> None:
    import matplotlib.pyplot as plt  # deferred: matplotlib

    plt.close(fig)


def _columns(widths: Sequence[str] | None, n: int) -> str:
    if widths is None:
        return str(n)
    if len(widths) != n:
        raise InputError(f"{len(widths)} column widths for {n} columns")
    return "(" + ", ".join(widths) + ",)"


def _typst_caption(caption: str) -> str:
    return f"[{esc(caption).text}]"


def _document_date(provenance: Provenance | None) -> str:
    if provenance is None or provenance.created is None:
        return "none"
    d = _dt.datetime.fromisoformat(provenance.created)
    return (
        f"datetime(year: {d.year}, month: {d.month}, day: {d.day}, hour: {d.hour}, "
        f"minute: {d.minute}, second: {d.second})"
    )


def _preamble(title: str, provenance: Provenance | None) -> str:
    keywords = ""
    if provenance is not None:  # the same fields as Provenance.pdf_metadata
        info = provenance.pdf_metadata(title)
        keywords = (
            f", description: {_typst_string(info['Subject'])}"
            f", keywords: ({_typst_string(info['Keywords'])},)"
        )
    short = title if len(title) <= 70 else title[:67] + "..."
    meta = f'title: {_typst_string(title)}, author: "soilstats", date: {_document_date(provenance)}'
    return f"""#set document({meta}{keywords})
#set page(paper: "{PAGE}", margin: (x: 2.2cm, top: 2.4cm, bottom: 2.4cm),
  header: context {{ if counter(page).get().first() > 1 [
    #set text(size: 8pt, fill: luma(90))
    #{_typst_string(short)} #h(1fr) soilstats ] }},
  footer: context [
    #set text(size: 8pt, fill: luma(90))
    #h(1fr) Page #counter(page).display("1 of 1", both: true) #h(1fr)])
#set text(size: {BODY_PT}pt, lang: "en")
#set par(justify: false, leading: 0.6em)
#set heading(numbering: "1.1")
#show heading.where(level: 1): set text(size: 13pt)
#show heading.where(level: 2): set text(size: 11pt)
#show figure.caption: set text(size: 8.5pt)
#show figure.where(kind: table): set block(breakable: true)
#show table.cell.where(y: 0): set text(weight: "bold")

"""
