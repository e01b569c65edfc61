"""The package version, in one place: pyproject.toml reads it (``dynamic = ["version"]``),
``grippers.__version__`` and ``grippers --version`` import it. A plain constant: it costs nothing at start-up.
"""

__version__ = "0.1.0"
