"""PLACEHOLDER (being written): PowerLibrary."""
class PowerLibrary:  # noqa: D101
    pass
