"""Real-browser tests. A package, so that its conftest is `browser.conftest`: a second
top-level `conftest` module would shadow tests/conftest.py for the tests that import it
(`from conftest import SimArm`), and its package-scoped fixtures end with this folder."""
