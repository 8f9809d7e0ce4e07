"""PLACEHOLDER (being written): discover."""
class Discovery:  # noqa: D101
    pass
class ExtendedModel:  # noqa: D101
    pass
def discover(*args, **kwargs):  # noqa: D103
    raise NotImplementedError
