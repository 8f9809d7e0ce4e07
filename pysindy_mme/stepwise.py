"""PLACEHOLDER (being written): FloatingFStepwise."""
class FloatingFStepwise:  # noqa: D101
    pass
