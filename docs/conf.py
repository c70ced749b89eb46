"""Sphinx configuration of the ias-gym documentation site (``make docs``).

Before reading the sources it runs the generators in ``docs/_scripts``: one page per
registered env id from its class docstring, the API pages from the package's modules, and
the results tables from the result JSON files beside the pages.
"""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_scripts"))
sys.path.insert(0, str(DOCS.parent))

import api_pages  # noqa: E402
import docstrings  # noqa: E402
import env_pages  # noqa: E402
import result_tables  # noqa: E402

env_pages.write_pages(DOCS / "envs")
api_pages.write_pages(DOCS / "api")
result_tables.write_tables(DOCS, DOCS / "_generated")

project = "ias-gym"
author = "the ias-gym developers"
copyright = "ias-gym developers, MIT licence"
release = "0.1.0"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinxarg.ext",
    "sphinx-mathjax-offline",  # MathJax from the package, not from a CDN
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "_scripts", "_generated", "README.md"]

myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
# myst.xref_missing: the notes link to source files (``../ias_gym/...``), left as text;
# ref.python: a name that two modules define (a re-export) links to the first of them
suppress_warnings = ["ref.python"]

# ignore-module-all: a module documents what it defines, not what its __all__ re-exports
# (else every re-exported class is described twice and its references are ambiguous)
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
# an env's step() would otherwise show Gymnasium's own docstring, written for another renderer
autodoc_inherit_docstrings = False
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
# numpy's ArrayLike by its name: expanded, it is a union of some twenty types
autodoc_type_aliases = {"ArrayLike": "numpy.typing.ArrayLike"}
autodoc_mock_imports = ["torch", "stable_baselines3", "ray"]
napoleon_google_docstring = True
napoleon_numpy_docstring = False
# an Attributes: section as fields of its class, not as attributes autodoc also documents
napoleon_use_ivar = True

html_theme = "furo"
html_title = "ias-gym"
html_static_path = ["_static"]
# a site icon: without one the browser asks for /favicon.ico and logs a 404
html_favicon = "_static/favicon.png"
html_last_updated_fmt = None


def setup(app: object) -> None:
    """The docstring fixes of ``docs/_scripts/docstrings.py`` before napoleon reads them."""
    app.connect("autodoc-process-docstring", docstrings.process, priority=100)  # type: ignore[attr-defined]
