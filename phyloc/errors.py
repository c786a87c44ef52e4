"""Exceptions raised by phyloc.

Every error a user can cause derives from :class:`PhylocError`; the command line prints its
message without a traceback and exits non-zero.

References
----------
Python Software Foundation, "Built-in Exceptions" (:class:`ValidationError` is also a
``ValueError``), https://docs.python.org/3/library/exceptions.html.
"""


class PhylocError(Exception):
    """Base class of the errors phyloc raises for bad input or unusable data."""


class ValidationError(PhylocError, ValueError):
    """A parameter is outside its allowed range or has the wrong shape.

    The message names the parameter (``field``), the value received and what is allowed.
    """

    def __init__(self, field: str, value, allowed: str):
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(f"{field} = {_short(value)} is not allowed: {allowed}")


def _short(value) -> str:
    """The value as the message shows it: one line (strings with control characters or
    surrounding blanks in quotes, as repr shows them). Plain text keeps up to 240 characters,
    so that a path the user gave is shown whole; anything else is cut at 80."""
    plain = isinstance(value, str) and value.isprintable() and value.strip() == value and value
    text = value if plain else repr(value)
    limit = 240 if plain else 80
    return text if len(text) <= limit else text[: limit - 3] + "..."
