"""Build busarm's API reference from its docstrings (pdoc), every warning an error.

``python docs/api_reference.py OUT``: HTML pages under OUT (``make docs``: build/api).
The modules' ``__all__`` say what each page shows.
"""

from __future__ import annotations

import pkgutil
import re
import sys
import warnings
from pathlib import Path

import pdoc
import pdoc.render

import busarm

PDOC_LIMIT = re.compile(r"Error parsing type annotation .*\[R\] for busarm\.bench\.\w+\.\w+"
                       r"\.__init__\. Import of R failed")
"""pdoc reads an inherited dataclass field's annotation (``runs: list[R]`` of the generic
``SeededBenchReport[R]``) in the subclass's module, where the base's TypeVar is not: its
limit, not a fault of the docstrings; the page shows the field unresolved."""
LEFT_OUT = ("busarm.__main__",)
"""Modules with no API of their own."""


def modules() -> list[str]:
    """busarm and every module below it, by name (pdoc follows a package's ``__all__``,
    which names no submodules: each is given)."""
    found = pkgutil.walk_packages(busarm.__path__, "busarm.")
    return ["busarm", *sorted(m.name for m in found if m.name not in LEFT_OUT)]


def build(out: Path) -> list[str]:
    """Write the reference to ``out``; the warnings pdoc gave (none is a good build)."""
    pdoc.render.configure(docformat="restructuredtext", show_source=False,
                          footer_text="busarm API reference")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pdoc.pdoc(*modules(), output_directory=out)
    return [f"{w.category.__name__}: {w.message}" for w in caught
            if ("pdoc" in Path(w.filename).parts or w.category is UserWarning)
            and not PDOC_LIMIT.search(str(w.message))]


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
