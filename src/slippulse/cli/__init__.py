"""cli: the ``slippulse`` command, thin over the library — ``steady``, ``dynamic`` and ``figures``
sub-commands, each a module with ``register(subparsers)``; errors become one line and exit code 2."""
from .app import UsageError, build_parser, main

__all__ = ['UsageError', 'build_parser', 'main']
