"""PLACEHOLDER (being written): MME."""
class MME:  # noqa: D101
    pass
