"""The conformance suites. A package, so that its conftest is `conformance.conftest`: a
second top-level `conftest` module would shadow tests/conftest.py for the tests that
import it (`from conftest import SimArm`)."""
