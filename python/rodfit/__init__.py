"""rodfit for Python (docs/python.md)."""
from ._core import *  # noqa: F401,F403
from ._core import __version__  # noqa: F401
