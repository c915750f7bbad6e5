"""
The tests' scan of the report's Markdown for numbers printed in more than one format: one format per quantity. It
finds whole numbers of 1,000 and more without thousands separators (ranges such as episode numbers ``1801-2000``,
dates and years of references excepted), p-values printed with fixed decimals where they are small (``0.0002``, not
``0.000215``), and table columns whose plain numbers carry different numbers of decimals ("35" beside "45.0"). Code
spans, links and file names are left alone.
"""

from __future__ import annotations

import re

from sb3_affect.study.report.rendering.formats import BARE, is_year

#: A p-value printed with fixed decimals below 0.001.
FIXED_P = re.compile(r"\bp (0\.000\d)\b")
#: A plain number in a table cell: optional sign, digits with separators, optional decimals.
NUMBER = re.compile(r"^[-+]?\d{1,3}(,\d{3})*(\.\d+)?$|^[-+]?\d+(\.\d+)?$")
#: Code spans, links and images: left alone.
CODE = re.compile(r"`[^`]*`|\]\([^)]*\)|!\[[^\]]*\]")


def prose(line: str) -> str:
    """``line`` without its code spans, links and images."""
    return CODE.sub(" ", line)


def bare_numbers(text: str, table: bool = False) -> list[str]:
    """The whole numbers of 1,000 and more in ``text`` without separators (a table line: skipped here, see below)."""
    if table:
        return []
    return [m.group(1) for m in BARE.finditer(text) if not is_year(text, m)]


def mixed_formats(markdown: str) -> list[str]:
    """Every number of ``markdown`` printed against the report's formats, one line per finding (empty: none)."""
    found = []
    lines = markdown.splitlines()
    for number, line in enumerate(lines, 1):
        text = prose(line)
        found += [f"line {number}: {n} without thousands separators" for n in bare_numbers(text, line.startswith("|"))]
        for match in FIXED_P.finditer(text):
            found.append(f"line {number}: p {match.group(1)} in fixed decimals (small p: 3 significant digits)")
    found += _table_columns(lines)
    return found


#: Tables whose rows, not columns, are quantities (the paper's spreadsheet layout): their columns mix formats by row.
ROW_TABLES = ("t-Test: Paired Two Sample for Means",)
#: Columns of settings (exact values as given, not measured quantities) and of the paper's cells as printed.
SETTING_COLUMNS = ("chosen ε", "alpha", "gamma", "values run", "printed")


def _significant(cell: str) -> int:
    digits = cell.lstrip("+-").replace(",", "").replace(".", "").lstrip("0")
    return len(digits)


def column_problem(cells: list[str]) -> str:
    """
    Why a column's plain numbers are in mixed formats ("" when they are not): numbers below 1,000 with decimals must
    share one number of decimals (fixed decimals) or all have 3 significant digits (``sig``), and a whole number
    below 1,000 (other than 0) may not stand among numbers with fixed decimals, nor one below 100 among numbers with
    decimals ("35" beside "45.0": 3 significant digits print it "35.0").
    """
    numbers = [c for c in cells if NUMBER.match(c)]
    small = [c for c in numbers if abs(float(c.replace(",", ""))) < 1000]
    decimals = [c for c in small if "." in c]
    counts = {len(c.split(".")[1]) for c in decimals}
    if len(counts) > 1 and not all(_significant(c) == 3 for c in decimals):
        return f"decimals {sorted(counts)}"
    whole = [c for c in small if "." not in c and c.lstrip("+-") != "0"]
    if whole and decimals:
        fixed = len(counts) == 1 and not all(_significant(c) == 3 for c in decimals)
        short = [c for c in whole if _significant(c) < 3]  # 3 significant digits print 35 as 35.0
        if fixed or short:
            return f"{(short or whole)[0]} beside {decimals[0]}"
    return ""


def _table_columns(lines: list[str]) -> list[str]:
    """Each Markdown table's columns whose plain numbers are in mixed formats (``column_problem``)."""
    found = []
    table: list[list[str]] = []
    start = 0
    for number, line in enumerate([*lines, ""], 1):
        if line.startswith("|"):
            if not table:
                start = number
            table.append([cell.strip() for cell in re.split(r"(?<!\\)\|", line.strip().strip("|"))])
            continue
        if len(table) > 2 and table[0][0] not in ROW_TABLES:
            header, rows = table[0], table[2:]
            kept = [row for row in rows if "as printed" not in row[0]]  # the paper's cells are quoted, not formatted
            for column in range(1, len(header)):
                if header[column] in SETTING_COLUMNS or "as printed" in header[column]:
                    continue
                found += [f"table at line {start}: {n} without thousands separators" for row in kept
                          if column < len(row) for n in bare_numbers(prose(row[column]))]  # fmt: skip
                problem = column_problem([row[column] for row in kept if column < len(row)])
                if problem:
                    found.append(f"table at line {start}, column {header[column]!r}: {problem}")
        table = []
    return found
