"""``python -m slippulse.cli`` runs the command."""
import sys

from .app import main

sys.exit(main())
