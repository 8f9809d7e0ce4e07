"""Independent references in exact arithmetic, shared by the test modules."""

from __future__ import annotations

from fractions import Fraction

import numpy as np


def exact_lstsq(A, y):
    """Least-squares solution of float data in exact rational arithmetic.

    The normal equations are formed and eliminated with ``Fraction``, so the
    only rounding is the final conversion to float: a reference for
    ill-conditioned problems that floating-point solvers get wrong.
    """
    F = [[Fraction(v) for v in row] for row in A]
    Y = [Fraction(v) for v in y]
    k = A.shape[1]
    M = [
        [sum(r[p] * r[q] for r in F) for q in range(k)]
        + [sum(r[p] * yy for r, yy in zip(F, Y, strict=True))]
        for p in range(k)
    ]
    for col in range(k):
        for row in range(col + 1, k):
            f = M[row][col] / M[col][col]
            M[row] = [a - f * b for a, b in zip(M[row], M[col], strict=True)]
    sol = [Fraction(0)] * k
    for row in reversed(range(k)):
        acc = M[row][k] - sum(M[row][j] * sol[j] for j in range(row + 1, k))
        sol[row] = acc / M[row][row]
    return np.array([float(s) for s in sol])


def exact_normal_inverse(A):
    """``(A^T A)^-1`` of float data in exact rational arithmetic (Gauss-Jordan)."""
    F = [[Fraction(v) for v in row] for row in A]
    k = A.shape[1]
    M = [
        [sum(r[p] * r[q] for r in F) for q in range(k)]
        + [Fraction(int(p == q)) for q in range(k)]
        for p in range(k)
    ]
    for col in range(k):
        pivot = M[col][col]
        M[col] = [v / pivot for v in M[col]]
        for row in range(k):
            if row != col and M[row][col] != 0:
                f = M[row][col]
                M[row] = [a - f * b for a, b in zip(M[row], M[col], strict=True)]
    return np.array([[float(v) for v in row[k:]] for row in M])
