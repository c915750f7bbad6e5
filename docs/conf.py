"""Sphinx configuration of the sb3-affect documentation (``make docs``)."""

from __future__ import annotations

import os
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
os.environ.setdefault("MPLBACKEND", "Agg")

import sb3_affect  # noqa: E402

project = "sb3-affect"
author = "the sb3-affect authors"
copyright = "2026, " + author
release = version = sb3_affect.__version__

extensions = [
    "sphinx.ext.autodoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = [
    "_build",
    "auto_examples/*.ipynb", "auto_examples/*.py", "auto_examples/*.zip", "**/sg_execution_times.rst",
]
root_doc = "index"

# Markdown pages (MyST): headings get anchors for [text](page.md#anchor) links, which -n checks.
# No math extension: formulas are plain text, so pages read the same offline (MathJax would load from the web).
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3

# API reference: the project's :param: docstrings, signatures with type hints, members in source order.
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_default_options = {"members": True, "show-inheritance": True}
autoclass_content = "class"
autodoc_inherit_docstrings = False  # document our own methods, not Gymnasium's or SB3's docstrings again

# Nitpicky mode (-n) checks every internal reference. Other projects' objects (SB3, Gymnasium, NumPy, ...) can not
# be resolved without their inventories (intersphinx needs the network), so references into them are not checked.
nitpicky = True
_EXTERNAL = (
    r"(stable_baselines3|sb3_contrib|gymnasium|pettingzoo|gym|numpy|np|pandas|pd|torch|th|pydantic|matplotlib|plt|tqdm|yaml|spaces)"
)
nitpick_ignore_regex = [
    (r"py:.*", _EXTERNAL + r"(\..*)?"),
    # the TypeVar of ``load`` (SB3's convention)
    (r"py:class", r"sb3_affect\.agents\.(tabular\.SelfTabular|model_files\.SelfFiles|action_repeat\.SelfRepeat)"),
    (r"py:class", r"(sb3_affect\.agents\.affectq\.)?SelfAffectQ"),  # the TypeVar of ``AffectQ.learn`` (SB3's convention)
    # internal types named in public signatures (a report section's context, a sweep's cell): described in interfaces
    (r"py:class", r"sb3_affect\.study\.(report\.reading\.context\.ReportContext|launcher\.schema\.Cell)"),
    # the store's checked view of a folder's files, handed from ``checked_files`` to ``results_parts`` (private module)
    (r"py:class", r"(sb3_affect\.study\.launcher\.folder_files\.)?FolderFiles"),
    # what the tabular loop takes from its agent (``TabularQAlgorithm.loop_parts``), described there
    (r"py:class", r"(sb3_affect\.agents\.reference_loop\.)?LoopParts"),
    # the Q-table the loop reads and writes while ``learn`` runs (``TabularQAlgorithm.loop_table``; private module)
    (r"py:class", r"(sb3_affect\.agents\.qtable\.)?LoopTable"),
    # the launcher's units of work and the deep and forensics study models, named in the launcher's signatures
    (r"py:class", r"sb3_affect\.study\.launcher\.(batches\.(Batch|Single))"),
    (r"py:.*", r"(collections\.abc|typing|pathlib|enum|types|os|argparse|io|random)\..*"),
    (r"py:.*", r"(GymEnv|Schedule|MaybeCallback|BaseCallback|BaseAlgorithm|BasePolicy|VecEnv|Env|Logger|Path|Figure|"
     r"Axes|DataFrame|Series|ndarray|NDArray|Tensor|Callable|Mapping|Sequence|Iterable|Iterator|Any|Self|TypeAlias|"
     r"EmotionRule|Geometry|SelfTabular|SelfFiles|SelfRepeat|Module|Task|OnResult|OnFailure|ObsType|ActType|SupportsFloat|RenderFrame|MazeSpec|_Context)"),
]

# Examples gallery: examples/plot_*.py run at build time; their figures appear on the pages.
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": str(DOCS / "auto_examples"),
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "show_memory": False,
    "write_computation_times": False,
}

html_theme = "sphinx_rtd_theme"
html_title = f"sb3-affect {version}"
html_static_path = ["_static"]
html_css_files = ["custom.css"]
html_theme_options = {"navigation_depth": 3, "collapse_navigation": False}
html_show_sourcelink = False
