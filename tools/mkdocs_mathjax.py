"""MkDocs hook: serve MathJax from the installed package, not from a CDN.

The `docs` extra installs `django-static-mathjax` (MathJax 3's own files, no dependencies; the
Django wrapper is not used). This hook adds its one-file SVG build, `tex-svg-full.js` (every TeX
extension included, the fonts drawn as SVG paths: nothing else is fetched), to the site as
`javascripts/mathjax/tex-svg-full.js`, so `mkdocs build` and `mkdocs serve` work offline.
`docs/javascripts/mathjax-config.js` tells it to typeset what pymdownx.arithmatex marks."""
from __future__ import annotations

import importlib.util
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File

TARGET = "javascripts/mathjax/tex-svg-full.js"


def mathjax_file() -> Path:
    """The installed MathJax build; PluginError (one line) when the package is missing."""
    spec = importlib.util.find_spec("mathjax")
    if spec is None or not spec.submodule_search_locations:
        raise PluginError("MathJax is not installed: pip install -e '.[docs]' "
                          "(django-static-mathjax)")
    path = Path(next(iter(spec.submodule_search_locations)), "static", "mathjax", "es5",
                "tex-svg-full.js")
    if not path.is_file():
        raise PluginError(f"{path} is missing: reinstall django-static-mathjax")
    return path


def on_files(files, config):
    files.append(File.generated(config, TARGET, abs_src_path=str(mathjax_file())))
    return files
