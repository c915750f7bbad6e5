"""
Numbers in the report's prose: whole numbers of 1,000 and more get thousands separators (ranges such as episode
numbers ``1801-2000``, dates and years of references excepted). The tests scan every page with the same pattern for
numbers printed without them.
"""

from __future__ import annotations

import re

#: A whole number of 4 or more digits standing alone (not part of a decimal, a word, a path or a longer number).
BARE = re.compile(r"(?<![\w.,/\-+:])(?<!et al\. )(\d{4,})(?![\w.,/%:\-]|\.\d)")


def with_separators(text: str) -> str:
    """``text`` with its whole numbers of 1,000 and more written with thousands separators (labels made elsewhere)."""
    return BARE.sub(lambda m: m.group(1) if is_year(text, m) else f"{int(m.group(1)):,}", text)


def is_year(text: str, match: re.Match[str]) -> bool:
    """A year after an author's name (``Jonker 2015``), not a count."""
    before = text[: match.start()].rstrip().split(" ")[-1] if text[: match.start()].strip() else ""
    return 1900 <= int(match.group(1)) <= 2099 and before[:1].isupper()
