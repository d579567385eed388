"""``python -m slippulse`` runs the ``slippulse`` command (an alias of the console script)."""
import sys

from .cli.app import main

sys.exit(main())
