"""Sphinx configuration of simucal's documentation (docs/): built offline, warnings as errors
(tests/test_docs.py runs `sphinx-build -W`; index.md says why Sphinx)."""
import simucal

project = "simucal"
author = "the simucal authors"
copyright = "2026, the simucal authors"  # the footer reads "(c) 2026, the simucal authors", not "(c). |"
release = version = simucal.__version__
extensions = [
    "myst_parser",  # the pages are Markdown, as the README they came from
    "sphinx.ext.autodoc",  # the API reference from simucal.api's docstrings
    "numpydoc",  # those docstrings' numpydoc sections
    "sphinx_click",  # the CLI reference from the click commands themselves
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build"]
myst_heading_anchors = 3  # links to a page's sections by their title, as on GitHub
numpydoc_show_class_members = False  # autodoc lists the members once
numpydoc_class_members_toctree = False
autodoc_member_order = "bysource"
html_theme = "alabaster"  # Sphinx's own: no web fonts, no CDN, so the pages open without a network
html_theme_options = {"description": "strapdown IMU calibration", "font_family": "sans-serif",
                      "head_font_family": "sans-serif",
                      # alabaster's 940 px page left code a 660 px column: 1280 px screens get 1240
                      "page_width": "min(1240px, 100%)", "body_max_width": "none"}
html_static_path = ["_static"]
html_css_files = ["simucal.css"]  # code blocks that fit the column (the file says how)
