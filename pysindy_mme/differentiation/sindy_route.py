"""The MME + SINDy route: the full model from ``SINDy(differentiation_method=MME)``.

With :class:`MME` as its differentiation method, a ``pysindy.SINDy`` model
regresses MME's model error ``d(t)`` on the library, so it holds only the
*correction* to the assumed model: ``model.print()`` shows ``(x1)' = 0.000``
for a state without error, ``simulate`` integrates the correction alone and
``score`` compares it with ``d``. :func:`extended_model_from_sindy` puts the
two together into an :class:`~pysindy_mme.ExtendedModel` (assumed model +
correction) that prints, predicts and simulates the whole right-hand side.

Two things this route cannot do, and :func:`check_sindy_route` says so
rather than stay silent:

* **Shrinkage.** ``d(t)`` is MME's *estimate* of the model error, smoothed
  by the weight ``W``; a regression on it gives coefficients that are
  biased toward zero (on the paper's Van der Pol record, polynomial
  library, 20 noise seeds: medians 0.947, 0.787, 0.787 of the true 1, 1, 1
  for the three terms, down to 0.63; asserted by the slow test in
  ``tests/differentiation/test_sindy_route.py``; the paper's own Table II
  has 0.81-0.99).
  :func:`pysindy_mme.discover` refits the terms on the measurements
  themselves (output error), which removes that bias, and gives confidence
  intervals and a test of each term.
* **Look-alikes.** Along one trajectory many library functions look alike
  (``x2`` and ``x2 |x2|``, ``x1^2 x2`` and ``|x1|^3 x2``). For every
  correction term the check finds the library functions that, swapped in
  for it, fit ``d(t)`` almost as well or better (residual sum of squares at
  most ``rss_ratio`` times the model's); the regression could not tell them
  apart, so its choice of function is not settled. ``discover`` settles it
  on the measurements (it swaps and merges look-alikes when that lowers the
  BIC). With the paper's Table I library this flags the poor choices the
  stepwise path makes (``x2 |x2|`` for ``x2``), and with a polynomial library
  on the same record no true term is flagged: the best swap at least doubles
  the residual there.
"""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.exceptions import NotFittedError

from ..core.tables import sig
from ..exceptions import DiscoveryWarning

__all__ = ["extended_model_from_sindy", "check_sindy_route", "look_alikes"]

SHRINKAGE_NOTE = (
    "the correction's coefficients were regressed on MME's estimate of d(t), "
    "which the estimator smooths and shrinks toward zero (on the paper's Van der "
    "Pol record, over 20 noise seeds, by a median of 5-21 % per term and up to "
    "37 %), and its terms were not tested against the measurements; for "
    "coefficients fitted to the measurements, with confidence intervals, a test "
    "of each term and the gain, use pysindy_mme.discover"
)


def _fitted_parts(mme, sindy_model):
    """``(coef, intercept, names, n_inputs)`` of the fitted SINDy model, checked."""
    if not hasattr(mme, "smoothed_x_"):
        raise NotFittedError(
            "mme is not fitted: fit the SINDy model with "
            "SINDy(differentiation_method=mme) first"
        )
    if not hasattr(sindy_model, "coefficients") or not hasattr(
        sindy_model, "feature_library"
    ):
        raise TypeError(
            "sindy_model must be a pysindy SINDy model, got "
            f"{type(sindy_model).__name__}"
        )
    if getattr(sindy_model, "differentiation_method", None) is not mme:
        raise ValueError(
            "sindy_model was not fitted with this MME as its differentiation_method; "
            "pass the MME given to SINDy(differentiation_method=...)"
        )
    try:
        coef = np.array(sindy_model.coefficients(), dtype=float)
    except (AttributeError, NotFittedError) as exc:
        raise NotFittedError(f"sindy_model is not fitted: {exc}") from None
    n = int(mme.n_states)
    if coef.ndim != 2 or coef.shape[0] != n:
        raise ValueError(
            f"sindy_model has {coef.shape[0]} equations but mme has {n} states; "
            "was it fitted on MME's model error (target='error')?"
        )
    if getattr(mme, "target", "error") != "error":
        raise ValueError(
            "mme.target must be 'error': with target='derivative' SINDy learned the "
            "whole right-hand side, not a correction to the assumed model"
        )
    n_inputs = int(getattr(sindy_model, "n_control_features_", 0) or 0)
    names = getattr(sindy_model, "feature_names", None)
    if names is None:
        names = [f"x{i}" for i in range(n)] + [f"u{k}" for k in range(n_inputs)]
    intercept = np.zeros(n)
    raw = getattr(getattr(sindy_model, "optimizer", None), "intercept_", None)
    if raw is not None and np.size(raw) == n:
        intercept = np.asarray(raw, dtype=float).reshape(n)
    errors = _error_states(mme)
    keep = np.zeros(n, dtype=bool)
    keep[errors] = True
    coef[~keep] = 0.0  # d is zero there: anything fitted is round-off
    intercept[~keep] = 0.0
    return coef, intercept, list(names), n_inputs


def _error_states(mme) -> np.ndarray:
    n = int(mme.n_states)
    es = mme.error_states
    return np.arange(n) if es is None else np.asarray(es, dtype=int).ravel()


def _library_data(mme, n_inputs) -> np.ndarray:
    """States (MME's estimate) and inputs on the sample grid, as SINDy saw them."""
    x = np.asarray(mme.smoothed_x_, dtype=float)
    if not n_inputs:
        return x
    u = mme.u
    if callable(u):
        u = u(np.asarray(mme.t_))
    u = np.asarray(u, dtype=float).reshape(x.shape[0], -1)
    return np.hstack([x, u])


def extended_model_from_sindy(mme, sindy_model, assumed_equations=None, check=True):
    """The assumed model plus the correction a SINDy model learned from MME.

    Parameters
    ----------
    mme : MME
        The fitted estimator, used as ``SINDy(differentiation_method=mme)``
        with ``target="error"`` (the default).
    sindy_model : pysindy.SINDy
        Fitted with ``mme`` (``model.fit(y, t=t, feature_names=...)``, ``y``
        the measured columns only).
    assumed_equations : list of str, optional
        Text of the assumed right-hand sides, for :meth:`ExtendedModel.print`.
    check : bool, default True
        Run :func:`check_sindy_route` and warn (``DiscoveryWarning``) with
        each note.

    Returns
    -------
    ExtendedModel
        ``dx/dt = f(x, t, u) + Theta(x, u) C^T``: prints, predicts and
        simulates the whole model. For a model with inputs pass ``u`` to
        ``simulate``.

    Raises
    ------
    NotFittedError
        ``mme`` or ``sindy_model`` is not fitted.
    ValueError
        ``sindy_model`` was fitted with another differentiation method, or
        ``mme.target`` is not ``"error"``.
    """
    from ..core.extended import ExtendedModel

    coef, intercept, names, n_inputs = _fitted_parts(mme, sindy_model)
    n = int(mme.n_states)
    model = ExtendedModel(
        mme.assumed_model,
        sindy_model.feature_library,
        coef,
        names[:n],
        names[n:],
        intercept=intercept,
        assumed_equations=assumed_equations,
        z_reference=_library_data(mme, n_inputs),
    )
    if check:
        for note in check_sindy_route(mme, sindy_model):
            warnings.warn(note, DiscoveryWarning, stacklevel=2)
    return model


def look_alikes(theta, d, selected, rss_ratio=1.5) -> dict:
    """Library columns that fit ``d`` about as well as each selected column.

    For each column ``k`` in ``selected``: the columns ``j`` (not selected,
    finite, not constant) for which the least-squares fit of ``d`` on
    ``selected`` with ``k`` replaced by ``j`` has a residual sum of squares
    at most ``rss_ratio`` times that of ``selected`` itself.

    Returns
    -------
    dict
        ``{k: [(j, rss_swap / rss, correlation of columns k and j)]}``,
        best first; only terms that have look-alikes.
    """
    theta = np.asarray(theta, dtype=float)
    d = np.asarray(d, dtype=float)
    selected = [int(k) for k in selected]
    finite = np.all(np.isfinite(theta), axis=0)
    finite[finite] = np.std(theta[:, finite], axis=0) > 0
    cand = [j for j in np.flatnonzero(finite) if j not in selected]
    if not selected or not cand:
        return {}
    coef_all = np.linalg.lstsq(theta[:, selected], d, rcond=None)[0]
    rss = float(np.sum((d - theta[:, selected] @ coef_all) ** 2))
    if not rss > 0:
        return {}
    out = {}
    for k in selected:
        others = [c for c in selected if c != k]
        r, cols = d.copy(), theta[:, cand].copy()
        if others:
            q, _ = np.linalg.qr(theta[:, others])
            r -= q @ (q.T @ r)
            cols -= q @ (q.T @ cols)
        norms = np.sum(cols**2, axis=0)
        ok = norms > 1e-12 * np.sum(theta[:, cand] ** 2, axis=0)
        swap = np.full(len(cand), np.inf)
        swap[ok] = r @ r - (cols[:, ok].T @ r) ** 2 / norms[ok]
        hits = [
            (cand[m], float(swap[m] / rss), _corr(theta[:, k], theta[:, cand[m]]))
            for m in np.argsort(swap)
            if swap[m] <= rss_ratio * rss
        ]
        if hits:
            out[k] = hits
    return out


def _corr(a, b) -> float:
    sa, sb = np.std(a), np.std(b)
    if not (sa > 0 and sb > 0):
        return float("nan")
    return float(np.mean((a - a.mean()) * (b - b.mean())) / (sa * sb))


def check_sindy_route(mme, sindy_model, rss_ratio=1.5, max_listed=3) -> list:
    """What a user of the MME + SINDy route must know about its result.

    Parameters
    ----------
    mme, sindy_model
        As for :func:`extended_model_from_sindy`.
    rss_ratio : float, default 1.5
        A library function is a look-alike of a correction term when swapping
        it in leaves the residual of the regression of ``d(t)`` at most this
        many times the model's (see the module docstring).
    max_listed : int
        Look-alikes named per term.

    Returns
    -------
    list of str
        One note per problem: the shrinkage of coefficients regressed on
        ``d(t)`` (whenever there is a correction), each term with look-alikes,
        and MME's own convergence.
    """
    coef, _, names, n_inputs = _fitted_parts(mme, sindy_model)
    notes = []
    if not getattr(mme, "converged_", True):
        notes.append(
            "MME did not converge: its d(t), and so the correction, may be poor"
        )
    if not np.any(coef):
        return notes
    notes.append(SHRINKAGE_NOTE)
    library = sindy_model.feature_library
    z = _library_data(mme, n_inputs)
    with np.errstate(all="ignore"):
        theta = np.asarray(library.transform(z), dtype=float)
    features = list(library.get_feature_names(names))
    d = np.asarray(mme.d_, dtype=float)
    for i in _error_states(mme):
        selected = np.flatnonzero(coef[i])
        found = look_alikes(theta, d[:, i], selected, rss_ratio)
        for k, hits in found.items():
            listed = ", ".join(
                f"{features[j]} (residual x{sig(ratio, 2)}, r = {sig(r, 2)})"
                for j, ratio, r in hits[:max_listed]
            )
            more = (
                f" and {len(hits) - max_listed} more" if len(hits) > max_listed else ""
            )
            notes.append(
                f"{features[k]} in ({names[i]})' has look-alikes along the estimate: "
                f"{listed}{more} fit d(t) about as well or better when swapped in "
                "(residual: sum of squares relative to the model's; r: correlation "
                "with the term), so the regression's choice of function is not "
                "settled; discover settles it on the measurements"
            )
    return notes
