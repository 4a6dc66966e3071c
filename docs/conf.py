"""Sphinx configuration of the uqdrape documentation: PyData theme, MyST Markdown pages,
numpydoc docstrings, sphinx-gallery examples executed at build time. It builds offline
(no intersphinx, nothing fetched) with warnings as errors: ``sphinx-build -W -b html docs docs/_build/html``."""

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent))  # the checkout's uqdrape, for a build from the checkout

import uqdrape  # noqa: E402

project = "uqdrape"
author = "uqdrape contributors"
copyright = "uqdrape contributors"
release = version = uqdrape.__version__

extensions = [
    "myst_parser",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx_gallery.gen_gallery",
    "studyref",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "_screenshots", "examples/README.rst", "**/*.toml"]
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

autosummary_generate = True
autodoc_default_options = {"members": True}
autodoc_member_order = "bysource"  # a module with __all__: in its order (the API in the order its docstring lists it)
numpydoc_show_class_members = False
numpydoc_validation_checks = set()

sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "reference_url": {},
    "capture_repr": (),  # show what an example prints, not the value of its last expression
}

html_theme = "pydata_sphinx_theme"
html_title = "uqdrape"
html_static_path = ["_static"]
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
    "secondary_sidebar_items": ["page-toc"],
}
html_sidebars = {"index": [], "changelog": [], "validation": ["sidebar-nav-bs"]}
html_show_sourcelink = False
