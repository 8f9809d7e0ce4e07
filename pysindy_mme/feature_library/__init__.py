"""Feature libraries: candidate functions of the states for the regression.

:class:`PowerLibrary` (``power.py``) is the function library of Kolodziej &
Mook's Table I as a pysindy feature library: signed and absolute powers of
each variable and their products. :class:`PhysicsLibrary` (``physics.py``)
holds named physical effects (Coulomb friction, saturation, Torricelli
outflow ..., the classes of ``effects.py``), each on the variable the user
chooses. A new library goes in a module of its own here (a
``pysindy.feature_library.base.BaseFeatureLibrary`` subclass), is exported
below, and gets its tests in ``tests/feature_library/``.
"""

from .effects import (
    Coulomb,
    DeadZone,
    Effect,
    Overflow,
    Saturation,
    SmoothCoulomb,
    Stribeck,
    Torricelli,
    ViscousSplit,
)
from .physics import PhysicsLibrary
from .power import PowerLibrary

__all__ = [
    "PowerLibrary",
    "PhysicsLibrary",
    "Effect",
    "Coulomb",
    "SmoothCoulomb",
    "Stribeck",
    "ViscousSplit",
    "Saturation",
    "DeadZone",
    "Torricelli",
    "Overflow",
]
