"""Sphinx configuration of the tromplab documentation.

Build: ``pip install -e ".[docs]"`` then ``python -m sphinx -W --keep-going -b html docs docs/_build/html``.
The CLI reference, the formula catalogue and the API list are generated from the code when
the build starts (``docs/_ext/tromplab_docs.py``); the gallery runs ``examples/plot_*.py``.
"""

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

import tromplab  # noqa: E402

project = "tromplab"
author = "tromplab developers"
copyright = "2026, tromplab developers"  # noqa: A001 - Sphinx's name
release = tromplab.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",  # MathJax 3 served with the site: the maths renders without a network
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "tromplab_docs",
]

# Smart quotes for quotes and ellipses only: "--ci" stays as typed, never an en dash.
smartquotes_action = "qe"

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_ext", "Thumbs.db", ".DS_Store", "sg_execution_times.rst"]
templates_path = ["_templates"]  # autosummary/class.rst: members in full, not a table of first sentences

# Markdown pages (the user guide) under myst: heading anchors for their '#section' links
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3

# API reference: autosummary pages with numpydoc sections; the docstrings are the package's,
# formatted for help() and doctests, so numpydoc's style validation stays off.
autosummary_generate = True
autosummary_imported_members = False
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks = set()
numpydoc_xref_param_type = False
numpydoc_attributes_as_param_list = True

# Gallery: the worked cases in examples/, run at every build
sphinx_gallery_conf = {
    "examples_dirs": "../examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"plot_",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "matplotlib_animations": False,
    "min_reported_time": 1,
    # no computation-times page: sphinx-gallery's loads jQuery and DataTables from a CDN, and the
    # site loads no remote script on any page (checked by .ci/check_offline_site.py)
    "write_computation_times": False,
}

html_theme = "pydata_sphinx_theme"
html_title = f"tromplab {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
html_static_path = []
html_show_sourcelink = False

# No warning is suppressed: the build runs with -W. The registry's docstrings cite
# [Shuvalov2018]_, defined once on the formula catalogue page (Sphinx citations are global).
