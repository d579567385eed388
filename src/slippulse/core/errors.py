"""Bad input that is not a physical parameter: command-line values, config and scan files."""


class UsageError(ValueError):
    """Bad command-line or config input (reported without a traceback, exit code 2)."""
