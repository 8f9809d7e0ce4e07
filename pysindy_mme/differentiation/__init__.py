"""Minimum model error estimation: the differentiation / denoising front-end.

:class:`MME` (``mme.py``) is the pysindy differentiation method; it checks
the problem and chooses ``W`` (``weight.py``: covariance constraint or
marginal likelihood). The estimate itself is computed by the
engine in :mod:`pysindy_mme.solver` (direct transcription, Gauss-Newton, the
banded KKT system, the observability checks), which also fits the study's
output-error models; the noise is read by :mod:`pysindy_mme.core.noise`,
and the priors on the model error (white, random walk, Gauss-Markov) are
objects in ``error_models/``, with their registry.
"""

from ..core.noise import difference_noise_variance, noise_covariance
from .mme import MME
from .sindy_route import check_sindy_route, extended_model_from_sindy

__all__ = [
    "MME",
    "check_sindy_route",
    "extended_model_from_sindy",
    "difference_noise_variance",
    "noise_covariance",
]
