"""Sphinx configuration of arfem's documentation site.

Build (warnings are errors, cross-references checked, the gallery executed):

    pip install -e ".[docs]"
    python -m sphinx -W --keep-going -n -b html docs docs/_build/html

The command pages' option tables are generated from the parsers by
``docs/gen_cli_reference.py`` and committed (so they read as plain Markdown too);
``tests/test_cli_reference.py`` fails when they differ from the installed commands.
"""
import logging
import os

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
html_static_path = ["_static"]
html_css_files = ["arfem.css"]          # tables that fit a phone
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
