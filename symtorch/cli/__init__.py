"""The ``symtorch`` command line, one module per command: :mod:`.main` (``detect``, ``info`` and the
parser), :mod:`.precompute`, :mod:`.show`."""
from .main import CLIError, build_parser, main

__all__ = ["main", "build_parser", "CLIError"]
