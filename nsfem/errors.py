"""Errors that carry a one-line message meant for the user."""


class NsfemError(Exception):
    """Base class of the errors nsfem reports to users without a traceback."""


class SceneError(NsfemError, ValueError):
    """A scene (or a mesh it names) is invalid; the message names the key and the reason."""

    def __init__(self, key: str, reason: str):
        self.key = key
        self.reason = reason
        super().__init__(f"{key}: {reason}" if key else reason)


class IntegrationError(NsfemError):
    """A time integration stopped before its end; ``result`` holds the run up to there
    (``completed`` False, ``info['error']`` the message), ready to be saved."""

    def __init__(self, message: str, result):
        self.result = result
        super().__init__(message)
