"""Old import path of :class:`ExtendedModel`; see :mod:`pysindy_mme.discovery`."""

from .discovery.extended import ExtendedModel

__all__ = ["ExtendedModel"]
