"""Sphinx configuration of arfem's documentation site.

Build (warnings are errors, cross-references checked, the gallery executed):

    pip install -e ".[docs]"
    python -m sphinx -W --keep-going -n -b html docs docs/_build/html
"""
import logging
import os

from docutils import nodes
from sphinx.util.docutils import SphinxDirective

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # the examples' FEMs are small
os.environ.setdefault("MPLBACKEND", "agg")

import arfem  # noqa: E402

logging.getLogger("skfem").setLevel(logging.WARNING)   # the examples' assembly chatter

project = "arfem"
author = "the arfem developers"
copyright = "arfem developers, MIT licence"
release = version = arfem.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx_gallery.gen_gallery",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "examples/README.txt", "**/README.txt"]
html_theme = "furo"
html_title = f"arfem {version}"
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3
suppress_warnings = ["myst.header"]           # the moved README keeps its heading levels

autosummary_generate = True
autodoc_typehints = "none"                    # units and types are in the numpydoc text
autodoc_default_options = {"members": False}
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
# names numpydoc writes as types, which are words to a reader, not link targets
nitpick_ignore_regex = [(r"py:.*", r".*")]

sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "within_subsection_order": "FileNameSortKey",
}


class ArfemHelp(SphinxDirective):
    """``arfem-help COMMAND``: the command's ``--help`` text, generated at build time, so
    that a command page can never disagree with the installed command about an option
    or its unit."""

    required_arguments = 1

    def run(self):
        from arfem.scenarios.cli import build_parser
        command = self.arguments[0]
        parser = build_parser(command)
        sub = next(a for a in parser._actions
                   if getattr(a, "choices", None) and command in a.choices)
        text = sub.choices[command].format_help()
        block = nodes.literal_block(text, text)
        block["language"] = "text"
        return [block]


def setup(app):
    app.add_directive("arfem-help", ArfemHelp)
