"""Sphinx configuration of the API reference (``make docs``; the choice: docs/decisions/emulator-runtime.md, D-7.20).

The reference is built from the docstrings of the three packages: autodoc reads them (with the ``#:`` comments of
attributes), napoleon reads their numpy-style ``Parameters`` sections, autosummary walks every module. The guide is
the markdown beside this file; only ``api/`` is a Sphinx source. ``make docs`` writes HTML to ``build/docs``
(git-ignored); ``.ci/run`` builds it with warnings as errors.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from protocols import __version__  # noqa: E402  (the version is declared once, there)

project = "psns-hil"
author = "psns-hil contributors"
version = release = __version__

extensions = ["sphinx.ext.autodoc", "sphinx.ext.autosummary", "sphinx.ext.napoleon", "sphinx.ext.viewcode"]
root_doc = "index"
templates_path = ["_templates"]  # autosummary reads it relative to the source folder, docs/api
exclude_patterns = ["_templates"]

# Members defined in each module, in source order; a package's re-exports (its ``__all__``) are documented where
# they are defined, once.
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autoclass_content = "class"
# The array aliases of firmware_model.arrays read as their names in signatures, not as expanded numpy generics.
autodoc_type_aliases = {name: f"firmware_model.arrays.{name}"
                        for name in ("FloatArray", "F64Array", "FloatDtype", "IntArray", "BoolArray")}
# ``python -m emulator`` runs the CLI when imported: walked past, not imported.
autodoc_mock_imports = ["emulator.__main__"]

napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
# An "Attributes" section becomes :ivar: fields: the attributes themselves are documented once, by autodoc.
napoleon_use_ivar = True

html_theme = "alabaster"
html_title = f"psns-hil {release} API reference"
html_show_sourcelink = False
