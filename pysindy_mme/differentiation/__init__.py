"""Minimum model error estimation: the differentiation / denoising front-end.

:class:`MME` (``mme.py``) is the pysindy differentiation method; it checks
the problem and chooses ``W`` (``weight.py``: covariance constraint or
marginal likelihood). The estimate itself is computed by direct
transcription (``transcription.py``: Gauss-Newton over every sample's state,
``kkt.py``: the banded KKT system), with the observability checks in
``observability.py``, the noise in ``noise.py`` and the priors on the model
error (white, random walk, ...) as objects in ``error_models/``, with their
registry. The same solver fits output-error models for the study.
"""

from .mme import MME
from .noise import difference_noise_variance, noise_covariance
from .sindy_route import check_sindy_route, extended_model_from_sindy
from .transcription import MMESmoother, SmootherResult, internal_unit

__all__ = [
    "MME",
    "MMESmoother",
    "SmootherResult",
    "check_sindy_route",
    "extended_model_from_sindy",
    "difference_noise_variance",
    "internal_unit",
    "noise_covariance",
]
