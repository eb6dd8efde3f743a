"""Build busarm's API reference from its docstrings (pdoc), every warning an error.

``python docs/api_reference.py OUT``: HTML pages under OUT (``make docs``: build/api).
The modules' ``__all__`` say what each page shows.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import pdoc
import pdoc.render

MODULES = ["busarm"]
"""Documented with every submodule below them."""


def build(out: Path) -> list[str]:
    """Write the reference to ``out``; the warnings pdoc gave (none is a good build)."""
    pdoc.render.configure(docformat="restructuredtext", show_source=False,
                          footer_text="busarm API reference")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pdoc.pdoc(*MODULES, output_directory=out)
    return [f"{w.category.__name__}: {w.message}" for w in caught
            if "pdoc" in Path(w.filename).parts or w.category is UserWarning]


def main() -> None:
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "build/api")
    said = build(out)
    for line in said:
        print(f"warning: {line}", file=sys.stderr)
    if said:
        sys.exit(1)
    print(f"API reference: {out / 'index.html'}")


if __name__ == "__main__":
    main()
