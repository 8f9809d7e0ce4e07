"""pysindy-mme: minimum model error estimation and floating-F stepwise regression.

Find what an assumed model gets wrong (:class:`MME`), explain the error with
a library of functions of the state (:class:`FloatingFStepwise`,
:class:`PowerLibrary`), and measure how much the extended model helps
(:func:`discover`; many studies at once, locally or on a Dask cluster:
:func:`discover_many`).
"""

from . import datasets
from ._version import __version__  # noqa: F401 (pysindy_mme.__version__)
from .core.noise import NoiseDiagnostics, estimate_noise_variance
from .differentiation import MME
from .differentiation.sindy_route import extended_model_from_sindy
from .discovery import Discovery, ExtendedModel, Parameter, discover
from .discovery.inputs import Record
from .discovery.many import StudyFailure, discover_many
from .discovery.options import StudyOptions
from .exceptions import (
    DiscoveryWarning,
    DivergenceError,
    ExcludedFeaturesWarning,
    NotSavedError,
    StepwiseCycleWarning,
    StudiesFailedError,
    UnobservableError,
)
from .feature_library import PhysicsLibrary, PowerLibrary
from .optimizers import FloatingFStepwise

__all__ = [
    "MME",
    "Discovery",
    "ExtendedModel",
    "Parameter",
    "Record",
    "StudyOptions",
    "FloatingFStepwise",
    "PowerLibrary",
    "PhysicsLibrary",
    "discover",
    "discover_many",
    "StudyFailure",
    "datasets",
    "estimate_noise_variance",
    "extended_model_from_sindy",
    "NoiseDiagnostics",
    "DiscoveryWarning",
    "DivergenceError",
    "ExcludedFeaturesWarning",
    "NotSavedError",
    "StepwiseCycleWarning",
    "StudiesFailedError",
    "UnobservableError",
]
