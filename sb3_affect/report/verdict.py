"""The verdict: each of the paper's claims, whether our runs support it, and by how much (text built from numbers)."""

from __future__ import annotations

from dataclasses import dataclass

from sb3_affect.report.document import Document


@dataclass
class Claim:
    """One claim of the paper, whether our numbers support it, and the numbers."""

    claim: str
    supported: bool
    evidence: str


def verdict(doc: Document, claims: list[Claim]) -> None:
    doc.h("Verdict")
    if not claims:
        doc.p("No claim of the paper could be checked with these results (both paper agents are needed).")
        return
    held = sum(c.supported for c in claims)
    doc.p(
        f"Of {len(claims)} checks, our runs support {held} and do not support {len(claims) - held}. "
        "Each line below is generated from the numbers above."
    )
    for c in claims:
        doc.p(f"- **{'Supported' if c.supported else 'Not supported'}**: {c.claim}. {c.evidence}.")
