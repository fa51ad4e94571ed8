"""Sphinx configuration of bfemp's documentation (``make docs``; docs/README.md says more).

Why Sphinx, sphinx-gallery and autodoc/napoleon (and not mkdocs-material with mkdocstrings):

- of the sites the issue names, scikit-fem (autodoc) and PyVista (autodoc, sphinx-gallery) are
  built with Sphinx, PolyFEM with mkdocs-material and meshio has its README only: Sphinx is what
  the Python projects of the field use, and what a user of bfemp will have met;
- sphinx-gallery runs the example scripts at build time and puts their pictures on the page,
  so the gallery is a test of the examples too (mkdocs-gallery is a port of it, with fewer users);
- autodoc imports the package and reads the docstrings bfemp already has (reST roles such as
  ``:func:`` and ``:mod:`` are used across the code; mkdocstrings would render them as text);
- myst-parser lets the hand-written pages be Markdown, which GitHub renders too, so the
  README's links into docs/ work on GitHub as well as on the built site.

Pages generated at build time (``_ext/bfemp_records.py``, written into ``generated/``): the
strategy table (``bfemp.strategy_table()`` and the conformance record), one page per benchmark
from ``benchmarks/records/``, and the trade study. Nothing there is copied by hand.

Environment variables: ``BFEMP_DOCS_QUICK=1`` runs one gallery example only (the tests' quick
build; ``make docs`` runs them all); ``BFEMP_DOCS_ROOT`` names the repository whose records and
package are documented (default: the folder above this one; the docs test builds a copy).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = Path(os.environ.get("BFEMP_DOCS_ROOT", HERE.parent)).resolve()
QUICK = os.environ.get("BFEMP_DOCS_QUICK", "") not in ("", "0")

sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE / "_ext"))

import bfemp  # noqa: E402

project = "bfemp"
author = "the bfemp authors"
copyright = "the bfemp authors, MIT licence"
release = version = bfemp.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "bfemp_records",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "README.md", "examples/README.txt", "**.ipynb_checkpoints"]
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3

# autodoc: the public API's docstrings, in source order, with type hints in the signature
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_default_options = {"members": True, "show-inheritance": False}
napoleon_google_docstring = True
napoleon_numpy_docstring = True
# the library's docstrings use ``literal`` and `name` for code; the default role renders the
# latter as code too (not as the reST default, emphasis)
default_role = "code"

# where bfemp_records reads the records from
bfemp_root = str(ROOT)

html_theme = "alabaster"
html_theme_options = {
    "description": "Coupled MPM-FEM simulation of elastic bodies in contact",
    "fixed_sidebar": True,
    "page_width": "1200px",
    "sidebar_width": "260px",
}
html_title = "bfemp"

# sphinx-gallery: docs/examples/plot_*.py run at build time; their figures (bfemp's own
# matplotlib Figures, never pyplot) are collected by bfemp_gallery.figure_scraper
sphinx_gallery_conf = {
    "examples_dirs": ["examples"],
    "gallery_dirs": ["auto_examples"],
    "filename_pattern": r"plot_shapes\.py" if QUICK else r"/plot_",
    "image_scrapers": ("bfemp_gallery.figure_scraper",),
    "reset_modules": (),
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "show_memory": False,
    "within_subsection_order": "FileNameSortKey",
}
