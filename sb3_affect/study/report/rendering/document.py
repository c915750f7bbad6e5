"""A minimal document model rendered to Markdown and to a self-contained HTML page (figures embedded)."""

from __future__ import annotations

import base64
import html
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd


def fmt(value: object, digits: int = 2) -> str:
    """
    A table cell: blank for missing values; ``digits`` decimals below 1,000 (a float keeps them when it is whole, so one
    column has one format: "35.0" beside "45.5"; an int is a count), whole numbers with thousands separators from
    1,000 on (a count of decisions has no meaningful decimals there), and a nonzero value too small for the decimals as
    the bound it is below (``< 0.001``), never in scientific notation beside its column's decimals.
    """
    if value is None:
        return ""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, float)):
        if isinstance(value, float) and math.isnan(value):
            return ""
        if isinstance(value, float) and math.isinf(value):
            return "inf"
        if abs(value) >= 1e3:
            return f"{value:,.0f}"
        if isinstance(value, int):
            return f"{value:,d}"
        if value != 0 and abs(value) < 10 ** (-digits):  # one notation in a column of decimals: a bound, not 1.47e-04
            return f"{'> -' if value < 0 else '< '}{10 ** (-digits):.{digits}f}"
        return f"{value:,.{digits}f}"
    return str(value)


def sig(value: float, digits: int = 3) -> str:
    """``value`` to ``digits`` significant digits (whole numbers with separators from 1,000 on; blank for NaN)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    value = float(value)
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if abs(value) >= 10 ** (digits - 1) or abs(value) >= 1e3 or (value.is_integer() and abs(value) < 1e3):
        return f"{value:,.0f}"
    if value == 0:
        return "0"
    if abs(value) < 1e-3:
        return f"{value:.{max(digits - 1, 1)}e}"
    decimals = max(digits - 1 - math.floor(math.log10(abs(value))), 0)
    return f"{value:.{decimals}f}"


def pval(p: float) -> str:
    """A p-value: 3 significant digits (``0.672``, ``0.0288``, ``0.000215``; ``2.15e-05`` below 1e-4), ``< 1e-300``
    where it underflows (never "0")."""
    if p is None or (isinstance(p, float) and math.isnan(p)):
        return ""
    if p < 1e-300:
        return "< 1e-300"
    if p < 1e-4:
        return f"{p:.2e}"
    return f"{p:#.3g}" if p < 1 else "1.00"


#: Table columns holding p-values (formatted by ``pval``).
_P_COLUMN = re.compile(r"^(p|p \(.*\)|P\(T<=t\).*|P (one|two)-tail|p, .*)$")


@dataclass
class Document:
    """
    Blocks in order: ("h", level, text), ("p", text), ("ul", items), ("table", frame, caption, digits),
    ("cards", frame, caption, digits, spec), ("md", markdown), ("img", path, caption), and ("part", name, title):
    the start of a page of its own (``part``).
    """

    title: str
    blocks: list[tuple] = field(default_factory=list)

    def h(self, text: str, level: int = 2) -> None:
        self.blocks.append(("h", level, text))

    def p(self, text: str) -> None:
        self.blocks.append(("p", text))

    def table(self, frame: pd.DataFrame, caption: str = "", digits: int = 2) -> None:
        self.blocks.append(("table", frame, caption, digits))

    def cards(self, frame: pd.DataFrame, caption: str, spec: CardSpec, digits: int = 2) -> None:
        """A table shown as one card per row in the HTML page (``spec``), as a table in the Markdown."""
        self.blocks.append(("cards", frame, caption, digits, spec))

    def ul(self, items: list[str]) -> None:
        """A bulleted list (each item inline text: **bold** and `code` spans)."""
        self.blocks.append(("ul", list(items)))

    def md(self, text: str) -> None:
        """A ready-made Markdown fragment (rendered to HTML with python-markdown's tables extension)."""
        self.blocks.append(("md", text))

    def img(self, path: Path, caption: str) -> None:
        self.blocks.append(("img", Path(path), caption))

    def part(self, name: str, title: str) -> None:
        """
        Start a page of its own: the blocks after it (up to the next ``part``) go to ``<name>.md`` and ``<name>.html``,
        an appendix linked from the main page (the blocks before the first ``part``).
        """
        if not re.fullmatch(r"[a-z0-9_-]+", name) or name == MAIN_PAGE:
            raise ValueError(f"part name {name!r}: lowercase letters, digits, '-' and '_' only, and not {MAIN_PAGE!r}")
        self.blocks.append(("part", name, title))

    def pages(self) -> list[tuple[str, str, list[tuple]]]:
        """``(file stem, title, blocks)`` of each page: the main page first, then each ``part`` (parts of one name join)."""
        pages: dict[str, tuple[str, list[tuple]]] = {MAIN_PAGE: (self.title, [])}
        current = MAIN_PAGE
        for block in self.blocks:
            if block[0] == "part":
                current = block[1]
                pages.setdefault(current, (block[2], []))
            else:
                pages[current][1].append(block)
        return [(name, title, blocks) for name, (title, blocks) in pages.items()]

    # -- rendering ----------------------------------------------------------------------------------------------
    def markdown(self, base: Path) -> str:
        """The main page in Markdown (``markdown_pages`` gives every page)."""
        return self.markdown_pages(base)[f"{MAIN_PAGE}.md"]

    def html(self) -> str:
        """The main page in HTML (``html_pages`` gives every page)."""
        return self.html_pages()[f"{MAIN_PAGE}.html"]

    def markdown_pages(self, base: Path) -> dict[str, str]:
        """Every page in Markdown by file name; the main page ends with the links to the others."""
        pages = self.pages()
        out = {}
        for name, title, blocks in pages:
            lines = [f"# {title}", ""]
            if name != MAIN_PAGE:
                lines += [f"Part of [{self.title}]({MAIN_PAGE}.md).", ""]
            lines += _markdown_blocks(blocks, base)
            if name == MAIN_PAGE and len(pages) > 1:
                lines += ["## Appendices", ""] + [f"- [{t}]({n}.md)" for n, t, _ in pages[1:]] + [""]
            out[f"{name}.md"] = "\n".join(lines)
        return out

    def html_pages(self) -> dict[str, str]:
        """
        Every page in HTML by file name: a contents column that stays in view (a bar across the top on narrow
        windows; it scrolls when longer than the window) listing the page's headings and the other pages, text at a
        readable width, wide tables scrolling inside their own box, cards in place of a card table's wide rows, and
        long tables folded on the appendix pages and after the appendix heading.
        """
        pages = self.pages()
        links = [(f"{n}.html", t) for n, t, _ in pages]
        return {
            f"{name}.html": _html_page(title, blocks, name != MAIN_PAGE, links, f"{name}.html")
            for name, title, blocks in pages
        }


#: The file stem of the main page (``report.md``, ``report.html``).
MAIN_PAGE = "report"


def _markdown_blocks(blocks: list[tuple], base: Path) -> list[str]:
    out: list[str] = []
    for block in blocks:
        kind = block[0]
        if kind == "h":
            out += [f"{'#' * block[1]} {block[2]}", ""]
        elif kind == "p":
            out += [block[1], ""]
        elif kind in ("table", "cards"):
            frame, caption, digits = block[1], block[2], block[3]
            if caption:
                out += [f"*{caption}*", ""]
            spec = block[4] if kind == "cards" else None
            out += [_md_cards(frame, digits, spec) if spec is not None and spec.markdown else md_table(frame, digits), ""]
        elif kind == "ul":
            out += [f"- {item}" for item in block[1]] + [""]
        elif kind == "md":
            out += [block[1], ""]
        elif kind == "img":
            rel = block[1].relative_to(base) if block[1].is_relative_to(base) else block[1]
            out += [f"![{block[2]}]({rel.as_posix()})", "", f"*{block[2]}*", ""]
    return out


def first_words(text: str) -> str:
    """A verdict's first words (``reproduced``, ``partly reproduced``, ``not reproduced`` ...): up to ``:``, ``;``, `` (``."""
    return text.split(":")[0].split(";")[0].split(" (")[0]


def _md_cards(frame: pd.DataFrame, digits: int, spec: CardSpec) -> str:
    """One list item per row: its title in bold, then the spec's Markdown columns (those with a value), labelled."""
    header, rows = _cells(frame, digits)
    lines = []
    for row in rows:
        cells = dict(zip(header[1:], row[1:]))
        lead = first_words(cells.get(spec.leads[0], "")) if spec.leads else ""
        shown = [
            f"{label}: {first_words(cells[name]) if name in spec.words else cells[name]}"
            for name, label in spec.markdown.items()
            if cells.get(name, "") not in ("", "n/a") and not (name in spec.words and first_words(cells[name]) == lead)
        ]
        lines.append(f"- **{row[0]}**. " + ". ".join(shown) + ("." if shown else ""))
    return "\n".join(lines)


def _html_page(title: str, blocks: list[tuple], appendix: bool, links: list[tuple[str, str]], own: str) -> str:
    """One page: its contents column (its own headings, then every page), its title and its blocks."""
    blocks = _split_md_headings(blocks)
    ids = _heading_ids(blocks)
    toc = "".join(
        f"<li class='toc{block[1]}'><a href='#{ids[i]}'>{html.escape(block[2])}</a></li>"
        for i, block in enumerate(blocks)
        if block[0] == "h" and block[1] <= 3
    )
    others = "".join(
        f"<li class='page'><b>{html.escape(t)}</b></li>"
        if f == own
        else f"<li class='page'><a href='{f}'>{html.escape(t)}</a></li>"
        for f, t in links
    ) if len(links) > 1 else ""
    pages = f"<b>Pages</b><ul>{others}</ul>" if others else ""
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        "<meta name='viewport' content='width=device-width, initial-scale=1'>",
        f"<title>{html.escape(title)}</title>",
        f"<style>{_CSS}</style></head><body><div class='layout'>",
        f"<nav class='toc'><b>Contents</b><ul>{toc}</ul>{pages}</nav><main>",
        f"<h1>{html.escape(title)}</h1>",
    ]
    fold = appendix
    for i, block in enumerate(blocks):
        kind = block[0]
        if kind == "h":
            fold = fold or (block[1] == 1 and block[2] == APPENDIX_HEADING)
            parts.append(f"<h{block[1]} id='{ids[i]}'>{html.escape(block[2])}</h{block[1]}>")
        elif kind == "p":
            parts.append(f"<p>{_inline(block[1])}</p>")
        elif kind == "table":
            frame, caption, digits = block[1], block[2], block[3]
            table = _html_table(frame, caption, digits)
            if fold and len(frame) > FOLD_ROWS:
                table = f"<details><summary>{_inline(caption)} ({len(frame)} rows)</summary>{table}</details>"
            parts.append(table)
        elif kind == "cards":
            parts.append(_html_cards(*block[1:]))
        elif kind == "ul":
            parts.append("<ul>" + "".join(f"<li>{_inline(item)}</li>" for item in block[1]) + "</ul>")
        elif kind == "md":
            import markdown  # (the report extra: only for the HTML document)

            parts.append(f"<div class='md'>{markdown.markdown(block[1], extensions=['tables', 'sane_lists'])}</div>")
        elif kind == "img":
            parts.append(f"<figure>{_img(block[1], block[2])}<figcaption>{_inline(block[2])}</figcaption></figure>")
    parts.append("</main></div></body></html>")
    return "\n".join(parts)


#: The level-1 heading that starts the appendix: its tables longer than ``FOLD_ROWS`` rows are folded in the HTML page.
APPENDIX_HEADING, FOLD_ROWS = "Appendix", 12

_CSS = (
    "body{margin:0;font-family:system-ui,-apple-system,'Segoe UI',sans-serif;line-height:1.5;color:#1d1d1d}"
    ".layout{display:grid;grid-template-columns:15rem minmax(0,1fr);gap:2.5rem;max-width:82rem;margin:0 auto;"
    "padding:0 1.2rem}"
    "nav.toc{position:sticky;top:0;align-self:start;box-sizing:border-box;max-height:100vh;overflow-y:auto;"
    "font-size:.82rem;padding:1.2rem .3rem 1.2rem 0;border-right:1px solid #e3e3e3}"
    "nav.toc ul{list-style:none;margin:.4rem 0;padding:0}nav.toc li{margin:.15rem 0}"
    "nav.toc .toc3{padding-left:1rem;font-size:.78rem}nav.toc a{color:#234;text-decoration:none}"
    "nav.toc a:hover{text-decoration:underline}"
    "main{min-width:0;padding:1rem 0 5rem}"
    "main>p,main>ul,main>h1,main>h2,main>h3,main>h4,.md>p,.md>ul,figcaption{max-width:46rem}"
    "h1,h2,h3,h4{scroll-margin-top:3.5rem;line-height:1.25}"
    ".tablebox,.md table{display:block;max-width:100%;overflow-x:auto}"
    "table{border-collapse:collapse;margin:.4rem 0 1.4rem;font-size:.85rem}"
    "td,th{border:1px solid #d0d0d0;padding:3px 8px;text-align:right;vertical-align:top}"
    "td.text{text-align:left;min-width:8rem;max-width:34rem}th{background:#f3f3f3;max-width:16rem}"
    "td:first-child,th:first-child{text-align:left}"
    "caption,figcaption,p.tcap{font-style:italic;color:#444;text-align:left;font-size:.85rem}"
    "p.tcap{max-width:46rem;margin:.8rem 0 .2rem}nav.toc .page{margin:.3rem 0}"
    "img{max-width:100%;height:auto}figure{margin:1rem 0 1.6rem}"
    "details{margin:.4rem 0 1.2rem}summary{cursor:pointer;color:#234;font-style:italic;font-size:.9rem}"
    ".cards{display:flex;flex-direction:column;gap:1rem;margin:.6rem 0 1.6rem}"
    ".card{border:1px solid #d6d6d6;border-radius:6px;padding:.6rem 1rem;background:#fcfcfc;"
    "display:flex;flex-wrap:wrap;gap:1rem}"
    ".card .body{flex:1 1 26rem;min-width:0}.card .fig{flex:0 1 20rem;margin:0}"
    ".card h4{margin:.2rem 0 .3rem}.card blockquote{margin:.1rem 0 .4rem;padding-left:.8rem;border-left:3px solid #bbb;"
    "color:#333;font-style:italic;font-size:.88rem}"
    ".card dl{display:grid;grid-template-columns:minmax(6rem,10rem) minmax(0,1fr);gap:.1rem .7rem;margin:0;"
    "font-size:.82rem;line-height:1.35}.card dt{color:#555}.card dd{margin:0}"
    ".verdict{font-weight:500;margin:.2rem 0 .35rem;font-size:.9rem;line-height:1.35}"
    ".verdict.yes{color:#1b6e20}.verdict.no{color:#a3261b}"
    ".verdict.mid{color:#8a5a00}"
    "@media (max-width:900px){.layout{display:block;padding:0 .8rem}"
    "nav.toc{position:sticky;top:0;z-index:2;background:#fff;max-height:none;border:0;border-bottom:1px solid #ccc;"
    "padding:.4rem 0;white-space:nowrap;overflow-x:auto;overflow-y:hidden}"
    "nav.toc ul,nav.toc li{display:inline;margin:0 .5rem 0 0}nav.toc .toc3{display:none}nav.toc b{margin-right:.6rem}}"
)


_MD_HEADING = re.compile(r"^(#{1,4}) (.+)$")


def _split_md_headings(blocks: list[tuple]) -> list[tuple]:
    """The blocks with each Markdown fragment's headings as heading blocks of their own (so the contents list them)."""
    out: list[tuple] = []
    for block in blocks:
        if block[0] != "md":
            out.append(block)
            continue
        chunk: list[str] = []
        for line in block[1].splitlines():
            match = _MD_HEADING.match(line)
            if match:
                if "".join(chunk).strip():
                    out.append(("md", "\n".join(chunk)))
                chunk = []
                out.append(("h", len(match.group(1)), match.group(2).strip()))
            else:
                chunk.append(line)
        if "".join(chunk).strip():
            out.append(("md", "\n".join(chunk)))
    return out


def _heading_ids(blocks: list[tuple]) -> dict[int, str]:
    """A unique anchor per heading block, from its text."""
    ids: dict[int, str] = {}
    seen: set[str] = set()
    for i, block in enumerate(blocks):
        if block[0] != "h":
            continue
        base = re.sub(r"[^a-z0-9]+", "-", block[2].lower()).strip("-")[:48] or "section"
        name, k = base, 2
        while name in seen:
            name, k = f"{base}-{k}", k + 1
        seen.add(name)
        ids[i] = name
    return ids


def _img(path: Path, alt: str) -> str:
    data = base64.b64encode(Path(path).read_bytes()).decode()
    return f"<img src='data:image/png;base64,{data}' alt='{html.escape(alt)}'>"


def _verdict_class(text: str) -> str:
    if text.startswith("reproduced"):
        return "yes"
    return "no" if text.startswith("not reproduced") else "mid"


def _html_cards(frame: pd.DataFrame, caption: str, digits: int, spec: CardSpec) -> str:
    """One card per row of ``frame``: its title, the quote, the lead column as the verdict, the rest as a list."""
    header, rows = _cells(frame, digits)
    out = [f"<div class='cards'><p class='caption'><i>{_inline(caption)}</i></p>"]
    for row in rows:
        cells = dict(zip(header[1:], row[1:]))
        title = row[0]
        body = [f"<h4>{html.escape(title)}</h4>"]
        if spec.quote in cells:
            body.append(f"<blockquote>{html.escape(cells[spec.quote])}</blockquote>")
        for lead in spec.leads:
            if lead in cells and cells[lead] not in ("", "n/a"):
                text = f"{html.escape(lead)}: {html.escape(cells[lead])}"
                body.append(f"<p class='verdict {_verdict_class(cells[lead])}'>{text}</p>")
        items = [(k, v) for k, v in cells.items() if k != spec.quote and k not in spec.leads and v not in ("", "n/a")]
        body.append("<dl>" + "".join(f"<dt>{html.escape(k)}</dt><dd>{html.escape(v)}</dd>" for k, v in items) + "</dl>")
        figure = spec.figures.get(title)
        side = ""
        if figure is not None and Path(figure).exists():
            name = html.escape(Path(figure).stem.replace("_", " "))
            side = f"<figure class='fig'>{_img(figure, title)}<figcaption>{name}</figcaption></figure>"
        out.append(f"<article class='card'><div class='body'>{''.join(body)}</div>{side}</article>")
    out.append("</div>")
    return "\n".join(out)


@dataclass
class CardSpec:
    """
    How a table shows as cards in the HTML page (the Markdown keeps the table).

    :param quote: the column shown as a quotation
    :param leads: the columns shown as verdicts, first (coloured by their first word)
    :param figures: a figure to show beside a row's card, by the row's index label
    :param markdown: the columns the Markdown shows, with their labels there, one list item per row (empty: the
        Markdown shows the whole table)
    :param words: the columns of ``markdown`` shown there by their first words only (``first_words``), and only where
        those differ from the first lead column's
    """

    quote: str = ""
    leads: tuple[str, ...] = ()
    figures: dict[str, Path] = field(default_factory=dict)
    markdown: dict[str, str] = field(default_factory=dict)
    words: tuple[str, ...] = ()


_EMPHASIS = re.compile(r"(?<![\w*])\*(?=\S)([^*]+?)(?<=\S)\*(?![\w*])")


def _inline(text: str) -> str:
    """Escape, then render **bold**, *emphasis* and `code` spans."""
    out = html.escape(text)
    pieces = out.split("**")
    out = "".join(f"<b>{p}</b>" if i % 2 else p for i, p in enumerate(pieces))
    out = _EMPHASIS.sub(r"<i>\1</i>", out)
    pieces = out.split("`")
    return "".join(f"<code>{p}</code>" if i % 2 else p for i, p in enumerate(pieces))


def _cells(frame: pd.DataFrame, digits: int) -> tuple[list[str], list[list[str]]]:
    index_name = frame.index.name or ""
    header: list[str] = [str(index_name), *[str(c) for c in frame.columns]]
    is_p = [bool(_P_COLUMN.match(str(c))) for c in frame.columns]
    rows = [
        [str(idx), *[pval(v) if p and isinstance(v, float) else fmt(v, digits) for v, p in zip(row, is_p)]]
        for idx, row in zip(frame.index, frame.itertuples(index=False))
    ]
    return header, rows


def _numeric(cell: str) -> bool:
    """Whether a table cell is one number (right-aligned in HTML; text is left-aligned)."""
    try:
        float(cell.replace(",", ""))
    except ValueError:
        return cell in ("", "inf", "yes", "no", "n/a", "< 1e-300")
    return True


def _md_cell(text: str) -> str:
    """
    A table cell's text for Markdown: a ``|`` does not end the cell, a ``<`` that would open an HTML tag is written as
    ``&lt;`` (a comparison such as ``P(T<=t)`` or ``< 1e-300`` stays as printed), one line.
    """
    text = re.sub(r"<(?=[A-Za-z/!?])", "&lt;", text)
    return text.replace("|", "\\|").replace("\r", " ").replace("\n", " ")


def md_table(frame: pd.DataFrame, digits: int) -> str:
    header, rows = _cells(frame, digits)
    header = [_md_cell(cell) for cell in header]  # a cell's own bars (|a - b|) never split the row
    rows = [[_md_cell(cell) for cell in row] for row in rows]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def _html_table(frame: pd.DataFrame, caption: str, digits: int) -> str:
    header, rows = _cells(frame, digits)
    # the caption stands above the table's scrolling box at the text's width, not inside a table wider than the page
    out = [f"<p class='tcap'>{_inline(caption)}</p>"] if caption else []
    out.append("<div class='tablebox'><table>")
    out.append("<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr>")
    for row in rows:
        out.append("<tr>" + "".join(f"<td{'' if _numeric(c) else ' class=text'}>{html.escape(c)}</td>" for c in row) + "</tr>")
    out.append("</table></div>")
    return "\n".join(out)
