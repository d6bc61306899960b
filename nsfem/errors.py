"""Errors that carry a one-line message meant for the user."""


class NsfemError(Exception):
    """Base class of the errors nsfem reports to users without a traceback."""


class SceneError(NsfemError, ValueError):
    """A scene (or a mesh it names) is invalid; the message names the key and the reason."""

    def __init__(self, key: str, reason: str):
        self.key = key
        self.reason = reason
        super().__init__(f"{key}: {reason}" if key else reason)
