"""Old import path of :class:`MME`; see :mod:`pysindy_mme.differentiation`."""

from .differentiation.mme import MME
from .differentiation.noise import difference_noise_variance, noise_covariance

__all__ = ["MME", "difference_noise_variance", "noise_covariance"]
