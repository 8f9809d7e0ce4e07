"""The notes on doubtful numbers name the quantities and say what to try."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from pysindy_mme.discovery.doubts import doubt_notes

NAMES = ["k", "x1 in x2'", "x1^3 in x2'"]


def _fit(theta, sd, corr, converged=True):
    sd = np.asarray(sd, dtype=float)
    cov = np.asarray(corr, dtype=float) * np.outer(sd, sd)
    return SimpleNamespace(
        theta=np.asarray(theta, dtype=float),
        covariance=cov,
        converged=converged,
        message="maximum number of iterations",
    )


def test_a_well_determined_converged_fit_gets_no_note():
    fit = _fit([2.0, -1.0, 0.5], [0.01, 0.02, 0.01], np.eye(3))
    assert doubt_notes(fit, NAMES) == []


def test_unconverged_fit_names_the_least_determined_first_and_what_to_try():
    # relative standard errors 0.5 %, 40 %, 10 %
    fit = _fit([2.0, -1.0, 0.5], [0.01, 0.4, 0.05], np.eye(3), converged=False)
    (note,) = doubt_notes(fit, NAMES)
    assert "did not converge (maximum number of iterations)" in note
    named = note.split("least determined ones: ")[1]
    assert named.index("x1 in x2'") < named.index("x1^3 in x2'") < named.index("k")
    assert "se 40 %" in named and "se 10 %" in named
    assert "Try:" in note and "noise_variance" in note


def test_look_alike_terms_are_named_with_their_correlation():
    corr = np.eye(3)
    corr[1, 2] = corr[2, 1] = -0.995
    fit = _fit([2.0, -1.0, 0.5], [0.01, 0.02, 0.01], corr)
    (note,) = doubt_notes(fit, NAMES)
    assert "x1 in x2' and x1^3 in x2' can hardly be told apart" in note
    assert "-0.995" in note


def test_undetermined_and_weak_quantities_are_named():
    fit = _fit([2.0, -1.0, 0.5], [np.nan, 0.5, 0.01], np.eye(3))
    notes = doubt_notes(fit, NAMES)
    assert any("hardly determine x1 in x2' (se 50 %)" in n for n in notes)
    assert any("not determined by the data (k:" in n for n in notes)
