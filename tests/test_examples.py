"""The examples gallery (examples/plot_*.py) runs at smoke size and draws what the documentation shows."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("plot_*.py"))


def test_there_are_examples() -> None:
    assert {p.stem for p in EXAMPLES} >= {"plot_first_affectq", "plot_compare_agents", "plot_sweep", "plot_custom_emotions"}


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_example_runs_and_draws(path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("SB3_AFFECT_SMOKE", "1")
    monkeypatch.setattr(sys, "argv", [str(path)])
    plt.close("all")
    runpy.run_path(str(path), run_name="__main__")
    figures = [plt.figure(n) for n in plt.get_fignums()]
    assert figures, f"{path.name} drew no figure"
    for figure in figures:
        drawn = [ax for ax in figure.axes if ax.lines or ax.patches or ax.collections]
        assert drawn, f"{path.name}: a figure with empty axes"
    assert capsys.readouterr().out.strip(), f"{path.name} printed nothing"
    plt.close("all")


def test_no_reference_outside_the_repository() -> None:
    """The project's docs carry their own definitions: nothing points at files beside the checkout."""
    texts = [ROOT / "README.md", *(ROOT / "docs").glob("*.md"), *(ROOT / "docs").glob("*.rst")]
    texts += [*(ROOT / "sb3_affect").rglob("*.py"), *(ROOT / "envs").rglob("*.py"), *(ROOT / "examples").glob("*.py")]
    offending = [str(p.relative_to(ROOT)) for p in texts if "../shared" in p.read_text() or "SPEC.md" in p.read_text()]
    assert offending == []
