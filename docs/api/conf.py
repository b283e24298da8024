"""Sphinx configuration of qfg's API reference (``make docs``: the pages in out/docs).

The reference is generated from the docstrings of the library's public modules: autosummary
writes one page per module (and per class and function) listing the names in its ``__all__``,
autodoc fills them in, napoleon reads the Google-style sections (``Args:``, ``Returns:``,
``Attributes:``). ``make docs`` builds from a copy of this directory (out/docs-src), so the
generated stubs never land in the checkout. tests/test_api_docs.py builds it too.
"""

import qfg

project = "qfg"
author = "the qfg authors"
release = qfg.__version__
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
]

templates_path = ["_templates"]
exclude_patterns = ["_build"]
root_doc = "index"

autosummary_generate = True
autosummary_ignore_module_all = False        # a module's page lists its __all__, in that order
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_preserve_defaults = True             # signatures show `seed=None`, not the object
autoclass_content = "both"

napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_ivar = True                     # "Attributes:" of dataclasses: no duplicate entries
napoleon_attr_annotations = True

html_theme = "alabaster"
html_title = f"qfg {release} API reference"
html_static_path = []
