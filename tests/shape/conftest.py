"""Fixtures shared with the edit tests: a real NGCDecoder with tube weights, the test GCs."""
from ..edit.conftest import gcs, module  # noqa: F401
