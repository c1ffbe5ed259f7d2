"""The export's one error: the scene cannot be solved as it is."""


class ExportError(ValueError):
    """The scene cannot be solved as it is; the message names the object and the problem."""
