"""The measurement noise: its covariance from the user, or estimated.

:func:`noise_covariance` turns what a user gives (one variance, one per
channel, or a full covariance ``R``) into ``R`` and checks it;
:func:`difference_noise_variance` is the classical difference-based
estimate behind ``noise_variance="auto"``.
"""

from __future__ import annotations

from math import comb

import numpy as np

from ..core.validation import as_float_array, check_positive_number

__all__ = ["difference_noise_variance", "noise_covariance"]


def difference_noise_variance(y, order: int = 4) -> np.ndarray:
    """Noise variance of each column of ``y`` from its ``order``-th differences.

    For ``y_k = s(t_k) + v_k`` with white noise ``v`` and a signal ``s``
    that is smooth on the scale of the sampling, the ``order``-th difference
    is dominated by the noise, whose variance it multiplies by
    ``sum_j C(order, j)^2 = C(2 order, order)`` (70 for order 4). This is the
    classical difference-based variance estimator; it overestimates the noise
    when the signal is not well resolved by the sampling. Missing values
    (NaN) are skipped.

    Returns
    -------
    ndarray (n_columns,)
    """
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    out = np.empty(y.shape[1])
    for j in range(y.shape[1]):
        col = y[~np.isnan(y[:, j]), j]
        if col.size <= order + 5:
            raise ValueError(
                f"noise_variance='auto' needs more than {order + 5} observed "
                f"samples in measured channel {j}; got {col.size}. Give "
                "noise_variance explicitly."
            )
        out[j] = np.mean(np.diff(col, n=order) ** 2) / comb(2 * order, order)
    return out


def noise_covariance(noise_variance, m: int) -> np.ndarray:
    """The (m, m) noise covariance R from a variance, one per channel, or R.

    Raises ``ValueError`` naming ``noise_variance`` when it is not finite and
    positive (definite), or does not match the ``m`` measured channels.
    """
    arr = as_float_array(noise_variance, "noise_variance", ndim=(0, 1, 2))
    if arr.ndim == 0:
        check_positive_number(float(arr), "noise_variance")
        return float(arr) * np.eye(m)
    if arr.ndim == 1:
        if arr.size != m:
            raise ValueError(
                f"noise_variance has {arr.size} entries but there are {m} "
                "measured channels"
            )
        if np.any(arr <= 0):
            raise ValueError(f"noise_variance must be positive, got {arr.tolist()}")
        return np.diag(arr)
    if arr.shape != (m, m):
        raise ValueError(
            f"noise_variance must be ({m}, {m}) for {m} measured channels, "
            f"got shape {arr.shape}"
        )
    if not np.allclose(arr, arr.T):
        raise ValueError("noise_variance (covariance R) must be symmetric")
    try:
        np.linalg.cholesky(arr)
    except np.linalg.LinAlgError:
        raise ValueError(
            "noise_variance (covariance R) must be positive definite"
        ) from None
    return arr
