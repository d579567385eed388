"""Bad input that is not a physical parameter: command-line values, config and scan files, and
files that do not follow the slippulse schema."""


class UsageError(ValueError):
    """Bad command-line or config input (reported without a traceback, exit code 2)."""


class SchemaError(ValueError):
    """A file or group that does not follow the slippulse schema (reported without a traceback,
    exit code 2; the message names the file and the group)."""
