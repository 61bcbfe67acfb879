"""The one exception type for failures a user can cause.

Bad problem files, unknown names, unreachable servers and malformed replies all raise
:class:`StalmError` with a message that names the file, field or name at fault, so the CLI can
print one clear line instead of a traceback.
"""


class StalmError(Exception):
    """A failure caused by input the user controls (files, names, servers, flags)."""


class StalmWarning(UserWarning):
    """Something the user should know that does not stop the run (a cache that cannot be
    written, so its contents are rebuilt each time). The CLI prints it as one ``warning:``
    line."""
