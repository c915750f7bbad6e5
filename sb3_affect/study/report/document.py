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
    A table cell: blank for missing values; ``digits`` decimals below 1,000, whole numbers with thousands separators
    from 1,000 on (a count of decisions has no meaningful decimals there), scientific notation for tiny values.
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
        if isinstance(value, int) or float(value).is_integer():
            return f"{value:,.0f}"
        if value != 0 and abs(value) < 10 ** (-digits):
            return f"{value:.2e}"
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
    """A p-value: 3 significant digits, ``< 1e-300`` where it underflows (never "0")."""
    if p is None or (isinstance(p, float) and math.isnan(p)):
        return ""
    if p < 1e-300:
        return "< 1e-300"
    if p < 1e-4:
        return f"{p:.2e}"
    return f"{p:.3g}" if p < 0.001 else f"{p:.4f}".rstrip("0").rstrip(".") if p < 1 else "1"


#: Table columns holding p-values (formatted by ``pval``).
_P_COLUMN = re.compile(r"^(p|p \(.*\)|P\(T<=t\).*|P (one|two)-tail|p, .*)$")


@dataclass
class Document:
    """
    Blocks in order: ("h", level, text), ("p", text), ("ul", items), ("table", frame, caption, digits),
    ("md", markdown), ("img", path, caption).
    """

    title: str
    blocks: list[tuple] = field(default_factory=list)

    def h(self, text: str, level: int = 2) -> None:
        self.blocks.append(("h", level, text))

    def p(self, text: str) -> None:
        self.blocks.append(("p", text))

    def table(self, frame: pd.DataFrame, caption: str = "", digits: int = 2) -> None:
        self.blocks.append(("table", frame, caption, digits))

    def ul(self, items: list[str]) -> None:
        """A bulleted list (each item inline text: **bold** and `code` spans)."""
        self.blocks.append(("ul", list(items)))

    def md(self, text: str) -> None:
        """A ready-made Markdown fragment (rendered to HTML with python-markdown's tables extension)."""
        self.blocks.append(("md", text))

    def img(self, path: Path, caption: str) -> None:
        self.blocks.append(("img", Path(path), caption))

    # -- rendering ----------------------------------------------------------------------------------------------
    def markdown(self, base: Path) -> str:
        out = [f"# {self.title}", ""]
        for block in self.blocks:
            kind = block[0]
            if kind == "h":
                out += [f"{'#' * block[1]} {block[2]}", ""]
            elif kind == "p":
                out += [block[1], ""]
            elif kind == "table":
                frame, caption, digits = block[1], block[2], block[3]
                if caption:
                    out += [f"*{caption}*", ""]
                out += [_md_table(frame, digits), ""]
            elif kind == "ul":
                out += [f"- {item}" for item in block[1]] + [""]
            elif kind == "md":
                out += [block[1], ""]
            elif kind == "img":
                rel = block[1].relative_to(base) if block[1].is_relative_to(base) else block[1]
                out += [f"![{block[2]}]({rel.as_posix()})", "", f"*{block[2]}*", ""]
        return "\n".join(out)

    def html(self) -> str:
        parts = [
            "<!DOCTYPE html><html><head><meta charset='utf-8'>",
            f"<title>{html.escape(self.title)}</title>",
            "<style>body{font-family:sans-serif;max-width:1300px;margin:2em auto;line-height:1.45}"
            "table{border-collapse:collapse;margin:0.5em 0 1.2em}td,th{border:1px solid #ccc;padding:3px 8px;"
            "text-align:right;vertical-align:top}td.text{text-align:left}th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}"
            "img{max-width:100%}figcaption,caption{font-style:italic;color:#444}</style></head><body>",
            f"<h1>{html.escape(self.title)}</h1>",
        ]
        for block in self.blocks:
            kind = block[0]
            if kind == "h":
                parts.append(f"<h{block[1]}>{html.escape(block[2])}</h{block[1]}>")
            elif kind == "p":
                parts.append(f"<p>{_inline(block[1])}</p>")
            elif kind == "table":
                frame, caption, digits = block[1], block[2], block[3]
                parts.append(_html_table(frame, caption, digits))
            elif kind == "ul":
                parts.append("<ul>" + "".join(f"<li>{_inline(item)}</li>" for item in block[1]) + "</ul>")
            elif kind == "md":
                import markdown

                parts.append(markdown.markdown(block[1], extensions=["tables", "sane_lists"]))
            elif kind == "img":
                data = base64.b64encode(block[1].read_bytes()).decode()
                parts.append(
                    f"<figure><img src='data:image/png;base64,{data}' alt='{html.escape(block[2])}'>"
                    f"<figcaption>{html.escape(block[2])}</figcaption></figure>"
                )
        parts.append("</body></html>")
        return "\n".join(parts)


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


def _md_table(frame: pd.DataFrame, digits: int) -> str:
    header, rows = _cells(frame, digits)
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def _html_table(frame: pd.DataFrame, caption: str, digits: int) -> str:
    header, rows = _cells(frame, digits)
    out = ["<table>"]
    if caption:
        out.append(f"<caption>{html.escape(caption)}</caption>")
    out.append("<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in header) + "</tr>")
    for row in rows:
        out.append("<tr>" + "".join(f"<td{'' if _numeric(c) else ' class=text'}>{html.escape(c)}</td>" for c in row) + "</tr>")
    out.append("</table>")
    return "\n".join(out)
