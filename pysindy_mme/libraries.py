"""Old import path of :class:`PowerLibrary`; see :mod:`pysindy_mme.feature_library`.

Kept so that ``from pysindy_mme.libraries import PowerLibrary`` keeps working.
"""

from .feature_library.power import PowerLibrary

__all__ = ["PowerLibrary"]
