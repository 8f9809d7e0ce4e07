"""Issue 20: the shortcuts of a cheaper confirmation stage against what they replace.

Each shortcut is checked on cases where the replaced computation also runs:
a band buffer reused from a dead factor against a fresh one (and two live
factors never sharing one), a resumed fit against a fresh fit from the same
point, the score tests from one pass of the variational equations against a
pass per candidate, and the row patterns of the noise against ``np.unique``.
"""

import gc

import numpy as np
import pytest

from pysindy_mme.solver import kkt
from pysindy_mme.solver import output_error as oe
from pysindy_mme.solver.kkt import BandedKKT, ReducedBorder
from pysindy_mme.solver.output_error import OutputErrorModel
from pysindy_mme.solver.transcription import mask_patterns
from pysindy_mme.systems import van_der_pol


def _blocks(N, n, seed):
    rng = np.random.default_rng(seed)
    Q = np.einsum("kij,klj->kil", *(2 * [rng.standard_normal((N, n, n))]))
    Q += np.eye(n)
    A = np.eye(n) + 0.1 * rng.standard_normal((N - 1, n, n))
    return Q, A


def test_live_factors_never_share_a_band_and_a_dead_ones_is_reused():
    N, n = 300, 2
    Q, A = _blocks(N, n, 0)
    Q2, A2 = _blocks(N, n, 1)
    rhs = np.random.default_rng(2).standard_normal((N, 2 * n))
    kkt._IDLE.clear()
    first = BandedKKT(N, n).factor(Q, A, None)
    alone = first.solve(rhs)
    second = BandedKKT(N, n).factor(Q2, A2, None)
    assert not np.shares_memory(first.lu, second.lu)
    # the first factor is intact after the second was made
    np.testing.assert_array_equal(first.solve(rhs), alone)
    buffer = first.lu
    del first
    gc.collect()
    (idle,) = kkt._IDLE
    assert np.shares_memory(idle, buffer)
    del buffer, idle
    third = BandedKKT(N, n).factor(Q, A, None)
    assert not kkt._IDLE  # the idle buffer was taken
    # the same answer as the fresh buffer gave
    np.testing.assert_array_equal(third.solve(rhs), alone)


def test_a_singular_system_gives_its_buffer_back():
    N, n = 50, 2
    kkt._IDLE.clear()
    Q = np.zeros((N, n, n))
    A = np.zeros((N - 1, n, n))
    with pytest.raises(np.linalg.LinAlgError):
        BandedKKT(N, n).factor(Q, A, None)
    assert len(kkt._IDLE) == 1


def test_a_smaller_system_factorises_in_a_larger_idle_band():
    # the held-out refits (a shorter record) reuse the whole record's band
    # rather than allocating a second one beside it; same answer as fresh
    N, n, M = 300, 2, 240
    kkt._IDLE.clear()
    Q, A = _blocks(M, n, 3)
    rhs = np.random.default_rng(4).standard_normal((M, 2 * n))
    alone = BandedKKT(M, n).factor(Q, A, None).solve(rhs)
    kkt._IDLE.clear()
    big = BandedKKT(N, n).factor(*_blocks(N, n, 5), None)
    buffer = big.lu
    del big
    gc.collect()
    small = BandedKKT(M, n).factor(Q, A, None)
    assert np.shares_memory(small.lu, buffer)
    assert not kkt._IDLE
    np.testing.assert_array_equal(small.solve(rhs), alone)
    del small
    gc.collect()
    # the whole buffer goes back, so the full-size system fits again
    (idle,) = kkt._IDLE
    assert idle.size == N * 2 * n * (6 * n - 2)


@pytest.mark.parametrize("m", [1, 3])
def test_mask_patterns_are_those_of_np_unique(m):
    rng = np.random.default_rng(m)
    for share in (0.0, 0.3, 0.9, 1.0):
        mask = rng.random((500, m)) >= share
        patterns, inverse = np.unique(mask, axis=0, return_inverse=True)
        ours, our_inverse = mask_patterns(mask)
        np.testing.assert_array_equal(ours, patterns)
        np.testing.assert_array_equal(our_inverse, np.ravel(inverse))


def _features(z, cols):
    x1, x2 = z[:, 0], z[:, 1]
    library = {
        0: np.ones_like(x1),
        1: x1,
        2: x2,
        3: x1**2,
        4: x1 * x2,
        5: x2**2,
        6: x1**3,
        7: x1**2 * x2,
        8: x1 * x2**2,
        9: x2**3,
    }
    return np.column_stack([library[c] for c in cols])


def _ignorance(x, t, u, p):
    return np.column_stack([x[:, 1], np.zeros(len(x))])


@pytest.fixture(scope="module")
def record():
    system = van_der_pol()
    t = system.time(20, 20)
    data = system.measure(3, t=t)
    engine = OutputErrorModel(
        _ignorance, 2, _features, data.y, data.t, None, np.eye(1) * 0.01, np.eye(2)[:1]
    )
    return engine, data


def test_a_resumed_fit_ends_where_a_fresh_fit_from_its_point_ends(record):
    engine, data = record
    slots = [(1, 1), (1, 2), (1, 7)]
    start = engine.fit(slots, np.array([-0.5, 0.5, -0.5]), data.x, max_iter=2)
    assert start.n_iter == 2 and not start.converged
    fresh = engine.fit(slots, start.theta, start.x, max_iter=50, tol=1e-9)
    resumed = engine.resume(start, max_iter=50, tol=1e-9)
    assert fresh.converged and resumed.converged
    np.testing.assert_allclose(resumed.theta, fresh.theta, rtol=1e-7, atol=1e-9)
    assert resumed.cost == pytest.approx(fresh.cost, rel=1e-9)
    np.testing.assert_allclose(resumed.std_errors, fresh.std_errors, rtol=1e-6)
    # the fit it went on from keeps its own result and statistics
    assert start.n_iter == 2
    assert np.all(np.isfinite(start.std_errors))


def test_resume_of_a_failed_fit_refits(record):
    engine, data = record
    failed = engine._failed(((1, 1),), np.array([-1.0]), data.x, "test")
    again = engine.resume(failed, max_iter=20)
    assert again.ok


def test_scores_from_one_pass_equal_a_pass_per_candidate(record, monkeypatch):
    engine, data = record
    fit = engine.fit([(1, 7)], np.array([-1.0]), data.x)
    pool = [(1, c) for c in range(10) if c != 7]
    together = engine.scores(fit, pool)
    monkeypatch.setattr(oe, "_FLOW_ELEMENTS", 1)
    monkeypatch.setattr(oe, "_SCORE_ELEMENTS", 1)
    one_by_one = engine.scores(fit, pool)
    np.testing.assert_allclose(together[0], one_by_one[0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(together[1], one_by_one[1], rtol=1e-9, atol=1e-12)
    assert np.argmax(together[0]) == np.argmax(one_by_one[0])


def _live_linearizations():
    from pysindy_mme.solver.records import Linearization

    return sum(isinstance(o, Linearization) for o in gc.get_objects())


def test_a_kkt_step_holds_only_the_current_linearization(record, monkeypatch):
    # the previous iteration's linearisation and the one the solve started
    # from used to stay alive through every later KKT step (at a study's
    # peak, two linearisations of the whole record beside the one in use)
    engine, data = record
    slots = [(1, 1), (1, 2), (1, 7)]
    # linearisations held elsewhere (fits of other tests) are not counted
    gc.collect()
    before = _live_linearizations()
    alive = []
    smoother = type(engine._solver(slots, np.zeros(3), 1, 1e-9))
    step = smoother._kkt_step

    def counting(self, lin, W, Winv):
        alive.append(_live_linearizations() - before)
        return step(self, lin, W, Winv)

    monkeypatch.setattr(smoother, "_kkt_step", counting)
    fit = engine.fit(slots, np.array([-0.5, 0.5, -0.5]), data.x, max_iter=6)
    assert fit.n_iter >= 3 and len(alive) == fit.n_iter
    assert max(alive) == 1


def _dense_kkt(Q, A, S=None):
    """The KKT matrix of kkt.py's docstring, written out densely."""
    N, n = Q.shape[0], Q.shape[1]
    m = 2 * n
    K = np.zeros((N * m, N * m))
    for k in range(N):
        x, lam = slice(k * m, k * m + n), slice(k * m + n, (k + 1) * m)
        K[x, x] = Q[k]
        if k == N - 1:
            K[lam, lam] = np.eye(n)  # the last block's dummy multiplier
            continue
        x_next = slice((k + 1) * m, (k + 1) * m + n)
        K[x, lam] = A[k].T
        K[lam, x] = A[k]
        K[lam, x_next] = -np.eye(n)
        K[x_next, lam] = -np.eye(n)  # -lam_k in x_{k+1}'s row
        if S is not None:
            K[lam, lam] = -S[k]
    return K


def _bordered(N, n, p, seed):
    Q, A = _blocks(N, n, seed)
    rng = np.random.default_rng(seed + 100)
    G = 0.3 * rng.standard_normal((N - 1, n, n))
    S = G @ np.swapaxes(G, 1, 2)
    E = rng.standard_normal((N, 2 * n, p))
    D = np.eye(p) * 1e3 + E.reshape(-1, p).T @ E.reshape(-1, p)
    return Q, A, S, E, D


@pytest.mark.parametrize("k", [None, 1, 3])
def test_the_reduced_solve_against_the_dense_bordered_system(k):
    # an independent reference: the bordered matrix [[K, E], [E^T, D]]
    # written out densely from the docstring's rows and solved by LU
    N, n, p = 40, 2, 3
    Q, A, S, E, D = _bordered(N, n, p, 5)
    rng = np.random.default_rng(6)
    shape = () if k is None else (k,)
    b = rng.standard_normal((N, 2 * n) + shape)
    c = rng.standard_normal((p,) + shape)
    Ef = E.reshape(-1, p)
    big = np.block([[_dense_kkt(Q, A, S), Ef], [Ef.T, D]])
    rhs = np.concatenate([b.reshape(N * 2 * n, -1), c.reshape(p, -1)])
    ref = np.linalg.solve(big, rhs)
    fac = BandedKKT(N, n).factor(Q, A, S)
    got = kkt.solve_reduced(fac, E, D, b, c)
    np.testing.assert_allclose(got.z.reshape(N * 2 * n, -1), ref[:-p], atol=1e-10)
    np.testing.assert_allclose(got.dtheta.reshape(p, -1), ref[-p:], atol=1e-10)
    # Sc is the reduced Hessian: D - E^T K^-1 E
    Sc = D - Ef.T @ np.linalg.solve(_dense_kkt(Q, A, S), Ef)
    np.testing.assert_allclose(got.Sc, Sc, rtol=1e-10)
    # only some samples of z: the same numbers
    part = kkt.solve_reduced(fac, E, D, b, c, rows=slice(3, 7))
    np.testing.assert_allclose(part.z, got.z[3:7], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(part.dtheta, got.dtheta)
    # the border eliminated once, the right-hand sides solved by columns
    border = kkt.ReducedBorder(fac, E, D)
    np.testing.assert_allclose(border.Sc, Sc, rtol=1e-10)
    cols = border.new_columns(1 if k is None else k)
    cols[:] = np.moveaxis(b.reshape(N, 2 * n, -1), 2, 0)
    dtheta = border.solve_columns(cols, c.reshape(p, -1))
    z = np.moveaxis(cols, 0, 2).reshape(N * 2 * n, -1)
    np.testing.assert_allclose(z, ref[:-p], atol=1e-10)
    np.testing.assert_allclose(dtheta, ref[-p:], atol=1e-10)


def test_a_factors_solve_of_a_few_rows_against_the_dense_system():
    # no border (p = 0): all samples, and only some (the initial state's
    # covariance needs sample 0 only, not a copy of the record's columns)
    N, n = 40, 2
    Q, A = _blocks(N, n, 9)
    b = np.random.default_rng(10).standard_normal((N, 2 * n, n))
    ref = np.linalg.solve(_dense_kkt(Q, A), b.reshape(N * 2 * n, n)).reshape(b.shape)
    fac = BandedKKT(N, n).factor(Q, A, None)
    np.testing.assert_allclose(fac.solve(b), ref, atol=1e-10)
    np.testing.assert_allclose(fac.solve(b, rows=slice(3, 7)), ref[3:7], atol=1e-10)
    part = kkt.solve_reduced(fac, None, np.zeros((0, 0)), b, None, rows=slice(0, 1))
    assert part.z.shape == (1, 2 * n, n)
    np.testing.assert_allclose(part.z, ref[:1], atol=1e-10)


def test_the_reduced_solve_keeps_no_copy_of_the_solved_columns():
    # solve_reduced solves [b, E] in one Fortran-ordered array of (k + p)
    # columns of the record and reads the answer where it lies: its peak
    # is that array and the states (it made C-ordered copies of all k + p
    # columns beside it: 8 columns at the peak for k = 1, p = 3, 10 for the
    # initial state's covariance, k = n = 2). The returned states own their
    # memory: a view of one column would keep all k + p alive.
    import tracemalloc

    N, n, p = 20_000, 2, 3
    Q, A, S, E, D = _bordered(N, n, p, 8)
    column = N * 2 * n * 8
    fac = BandedKKT(N, n).factor(Q, A, S)
    # k = 1: [b, E] and the returned states (the product subtracted from
    # K^-1 b is added in place by BLAS, not made beside it)
    for k, rows, allowed in [(1, None, 4 + 1), (2, slice(0, 1), 5)]:
        b = np.zeros((N, 2 * n, k))
        b[0, :n, :] = np.eye(n)[:, :k]
        c = np.zeros((p, k))
        tracemalloc.start()
        try:
            base = tracemalloc.get_traced_memory()[0]
            sol = kkt.solve_reduced(fac, E, D, b, c, rows=rows)
            peak = tracemalloc.get_traced_memory()[1] - base
        finally:
            tracemalloc.stop()
        assert peak <= (allowed + 0.2) * column, (k, peak / column)
        assert sol.z.base is None or sol.z.base.size == sol.z.size
    # a group's solve against an eliminated border: nothing the size of its
    # columns beside them (the product K^-1 E dtheta was one column each)
    border = ReducedBorder(fac, E, D)
    cols = border.new_columns(2)
    cols[:, 0, :n] = np.eye(n)
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        border.solve_columns(cols, np.zeros((p, 2)))
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert peak <= 0.2 * column, peak / column


@pytest.mark.parametrize("layout", ["contiguous", "strided"])
def test_subtract_product_is_the_numpy_product(layout):
    rng = np.random.default_rng(3)
    out = rng.standard_normal((3, 50))
    b = rng.standard_normal((4, 50))
    a = rng.standard_normal((4, 3))
    if layout == "strided":  # not C-ordered: the numpy fallback
        out, b = np.asfortranarray(out), rng.standard_normal((4, 100))[:, ::2]
    expected = out - a.T @ b
    before = out.__array_interface__["data"][0]
    kkt.subtract_product(out, a, b)
    np.testing.assert_allclose(out, expected, rtol=1e-13, atol=1e-13)
    assert out.__array_interface__["data"][0] == before


class _CountedFeatures:
    """``_features`` with its exact gradient, counting evaluations."""

    def __init__(self):
        self.calls = 0

    def __call__(self, z, cols):
        self.calls += 1
        return _features(z, cols)

    def gradient(self, z, cols):
        x1, x2 = z[:, 0], z[:, 1]
        zero, one = np.zeros_like(x1), np.ones_like(x1)
        grads = {
            1: (one, zero),
            2: (zero, one),
            7: (2 * x1 * x2, x1**2),
        }
        return np.stack([np.column_stack(grads[c]) for c in cols], axis=1)


def test_a_linearization_evaluates_the_library_once_per_stage(record, monkeypatch):
    # the Jacobian of each RK4 stage is taken right after its value, at the
    # same point, so the model's library columns there are reused (they were
    # evaluated twice per stage); the same linearisation to the last bit
    engine, data = record
    features = _CountedFeatures()
    counted = OutputErrorModel(
        _ignorance, 2, features, data.y, data.t, None, engine.R, engine.measurement
    )
    slots, theta = [(1, 1), (1, 2), (1, 7)], np.array([-1.0, 1.0, -1.0])
    solver = counted._solver(slots, theta, 1, 1e-9, data.x)
    x, d = data.x / solver.unit, np.zeros((data.t.size - 1, 0))
    features.calls = 0  # (the solver's units evaluated it once)
    lin = solver.linearize(x, d, theta)
    assert features.calls == 4 * solver.n_substeps  # one per RK4 stage

    # the same numbers as a model that evaluates its library every time
    from pysindy_mme.core.model import ParametricModel

    monkeypatch.setattr(
        ParametricModel,
        "_phi",
        lambda self, x, u: self.features(self._z(x, u), self.used),
    )
    features.calls = 0
    again = solver.linearize(x, d, theta)
    assert features.calls == 8 * solver.n_substeps
    for name in ("A", "B", "defects", "r"):
        np.testing.assert_array_equal(getattr(lin, name), getattr(again, name))


@pytest.mark.parametrize("substeps", [1, 3])
def test_the_candidates_flow_without_state_columns_gives_the_same_sensitivities(
    record, substeps
):
    # each column of the flow's derivatives is propagated on its own through
    # the stages' Jacobians: the candidates' columns alone (the score tests'
    # pass) are the very numbers of the pass that carries A and B beside them
    engine, data = record
    slots = [(1, 1), (1, 2), (1, 7)]
    solver = engine._solver(slots, np.array([-1.0, 1.0, -1.0]), 1, 1e-9)
    solver.n_substeps = substeps
    x = data.x / solver.unit
    d = np.zeros((solver.N - 1, 0))
    cols = [0, 3, 9]

    def forcing(z, s, u):
        phi = _features(solver.unit * z, cols)
        out = np.zeros((z.shape[0], 2, 3))
        out[:, 1, :] = phi
        out[:, 0, 2] = phi[:, 1]
        return out / solver.unit[:, None]

    theta = np.array([-1.0, 1.0, -1.0])
    phi, A, G, B, full = solver.flow(x, d, theta, extra=(3, forcing))
    phi_lean, lean = solver.flow(x, d, theta, extra=(3, forcing), only_extra=True)
    np.testing.assert_array_equal(lean, full)
    np.testing.assert_array_equal(phi_lean, phi)
    assert np.abs(lean).max() > 0


def test_a_fits_statistics_reuse_its_last_steps_factor(record, monkeypatch):
    # the covariance and the score tests of a converged fit factorise the
    # matrix of its last Gauss-Newton step: kept, that factor serves them
    # (the same numbers as a fresh factorisation), until any other
    # factorisation wants a band
    engine, data = record
    slots = [(1, 1), (1, 2), (1, 7)]
    fit = engine.fit(slots, np.array([-1.0, 1.0, -1.0]), data.x, tol=1e-9)
    assert fit.converged
    calls = []
    factor = BandedKKT.factor

    def counting(self, Q, A, S):
        calls.append(A.shape[0])
        return factor(self, Q, A, S)

    monkeypatch.setattr(BandedKKT, "factor", counting)
    cov = fit.covariance.copy()
    pool = [(1, c) for c in (0, 3, 9)]
    scores = engine.scores(fit, pool)
    assert calls == []
    # the same numbers from a fresh factorisation
    kkt.drop_kept_factor()
    fit._cov = None
    np.testing.assert_array_equal(fit.covariance, cov)
    np.testing.assert_array_equal(engine.scores(fit, pool)[0], scores[0])
    # once dropped, the covariance factorises again and keeps its factor for
    # the score tests
    assert calls == [data.t.size - 1]  # A: one block per interval


def test_a_kept_factor_gives_its_band_to_the_next_factorisation():
    N, n = 300, 2
    Q, A = _blocks(N, n, 0)
    Q2, A2 = _blocks(N, n, 1)
    kkt._IDLE.clear()
    kkt.drop_kept_factor()
    key = (A, "test")
    first = BandedKKT(N, n).factor(Q, A, None)
    band = first.lu.base if first.lu.base is not None else first.lu
    kkt.keep_factor(key, first)
    del first
    assert kkt.kept_factor(key) is not None
    assert kkt.kept_factor((A2, "test")) is None  # another matrix
    assert kkt.kept_factor((A, "other")) is None
    second = BandedKKT(N, n).factor(Q2, A2, None)
    assert kkt.kept_factor(key) is None  # dropped for the new factor...
    assert np.shares_memory(second.lu, band)  # ...which took its band
    assert not kkt._IDLE


@pytest.mark.parametrize("offsets", [False, True])
def test_the_border_by_blocks_is_the_dense_border(offsets):
    # the KKT step's E kept as its blocks (B from the linearisation, the
    # offsets' rows or None) against the same E written out: the products,
    # a parameter subset and the bordered solve (dense reference)
    N, n, p = 30, 2, 3
    Q, A, S, _, D = _bordered(N, n, p, 11)
    rng = np.random.default_rng(12)
    Ex = rng.standard_normal((N, n, p)) if offsets else None
    B = rng.standard_normal((N - 1, n, p))
    border = kkt.Border(Ex, B, N, n, p)
    E = np.zeros((N, 2 * n, p))
    if offsets:
        E[:, :n] = Ex
    E[:-1, n:] = B
    np.testing.assert_array_equal(border.dense(), E)
    cols = rng.standard_normal((4, N, 2 * n))
    ref = E.reshape(-1, p).T @ cols.reshape(4, -1).T
    np.testing.assert_allclose(border.t_dot(cols), ref, rtol=1e-13, atol=1e-12)
    v = rng.standard_normal(p)
    np.testing.assert_allclose(border.dot(v), E @ v, rtol=1e-13, atol=1e-13)
    keep = np.array([True, False, True])
    np.testing.assert_array_equal(border.columns(keep).dense(), E[:, :, keep])
    fac = BandedKKT(N, n).factor(Q, A, S)
    b, c = rng.standard_normal((N, 2 * n)), rng.standard_normal(p)
    Ef = E.reshape(-1, p)
    big = np.block([[_dense_kkt(Q, A, S), Ef], [Ef.T, D]])
    sol = np.linalg.solve(big, np.concatenate([b.ravel(), c]))
    got = kkt.solve_reduced(fac, border, D, b, c)
    np.testing.assert_allclose(got.z.ravel(), sol[:-p], atol=1e-10)
    np.testing.assert_allclose(got.dtheta, sol[-p:], atol=1e-10)
    reduced = kkt.ReducedBorder(fac, border, D)
    many = reduced.new_columns(1)
    many[0] = b
    np.testing.assert_allclose(
        reduced.solve_columns(many, c[:, None])[:, 0], sol[-p:], atol=1e-10
    )
    np.testing.assert_allclose(many[0].ravel(), sol[:-p], atol=1e-10)


def test_keep_statistics_keeps_the_numbers_and_releases_the_linearisation(record):
    engine, data = record
    slots = [(1, 1), (1, 2), (1, 7)]
    kept = engine.fit(slots, np.array([-0.5, 0.5, -0.5]), data.x, max_iter=50)
    released = engine.fit(slots, np.array([-0.5, 0.5, -0.5]), data.x, max_iter=50)
    assert released.keep_statistics() is released
    assert released._state is None
    np.testing.assert_array_equal(released.theta, kept.theta)
    np.testing.assert_allclose(released.covariance, kept.covariance, rtol=1e-12)
    np.testing.assert_allclose(released.x0_covariance, kept.x0_covariance, rtol=1e-12)
    assert released.inflation == kept.inflation
    np.testing.assert_allclose(released.std_errors, kept.std_errors, rtol=1e-12)
    # what needs the linearisation refuses the fit, and says why
    with pytest.raises(ValueError, match="no longer holds"):
        engine.scores(released, [(1, 3)])
    with pytest.raises(ValueError, match="no longer holds"):
        engine.integrator_effect(released)
    # resuming refits from the fit's point, and ends where it ended
    again = engine.resume(released, max_iter=50, tol=1e-9)
    np.testing.assert_allclose(again.theta, kept.theta, rtol=1e-6)
    # a second call is harmless
    released.keep_statistics()
    np.testing.assert_allclose(released.covariance, kept.covariance, rtol=1e-12)


def test_a_fit_loaded_from_a_file_refuses_score_tests(record):
    """A saved fit keeps its numbers, not its solver: a score test on it
    says so instead of returning zeros (no candidate would enter)."""
    from pysindy_mme.discovery import storage

    engine, data = record
    fit = engine.fit([(1, 1), (1, 2), (1, 7)], np.array([-0.5, 0.5, -0.5]), data.x)
    loaded = storage._fit(storage._fit_dict(fit))
    np.testing.assert_array_equal(loaded.covariance, fit.covariance)
    with pytest.raises(ValueError, match="loaded from a file"):
        engine.scores(loaded, [(1, 3)])


@pytest.mark.parametrize("offsets", [False, True])
def test_a_kept_border_serves_later_solves_and_its_subsets(offsets):
    # K^-1 E kept with the factor by one bordered solve (a Gauss-Newton
    # step) serves later solves with the same border, or with some of its
    # parameters (a parameter held on a bound), and the border eliminated
    # for score tests: against the dense bordered system, and with only the
    # right-hand sides' columns solved
    N, n, p = 30, 2, 3
    Q, A, S, _, D = _bordered(N, n, p, 21)
    rng = np.random.default_rng(22)
    Ex = rng.standard_normal((N, n, p)) if offsets else None
    border = kkt.Border(Ex, rng.standard_normal((N - 1, n, p)), N, n, p)
    E = border.dense()
    fac = BandedKKT(N, n).factor(Q, A, S)
    first = kkt.solve_reduced(
        fac, border, D, rng.standard_normal((N, 2 * n)), np.zeros(p), keep_border=True
    )
    # the offsets' rows are a product made anew at each call: not kept
    assert (fac.border is None) == offsets
    solved = []
    solve = fac.solve_in_place

    def counting(cols):
        solved.append(cols.shape[1])
        return solve(cols)

    fac.solve_in_place = counting
    b, c = rng.standard_normal((N, 2 * n, 2)), rng.standard_normal((p, 2))
    for keep in (np.ones(p, bool), np.array([True, False, True])):
        Ek, Dk = (border, D) if keep.all() else (border.columns(keep), D[keep][:, keep])
        Ef = E[:, :, keep].reshape(-1, keep.sum())
        big = np.block([[_dense_kkt(Q, A, S), Ef], [Ef.T, Dk]])
        ref = np.linalg.solve(big, np.concatenate([b.reshape(-1, 2), c[keep]]))
        got = kkt.solve_reduced(fac, Ek, Dk, b, c[keep])
        np.testing.assert_allclose(got.z.reshape(-1, 2), ref[: -keep.sum()], atol=1e-10)
        np.testing.assert_allclose(got.dtheta, ref[-keep.sum() :], atol=1e-10)
        reduced = kkt.ReducedBorder(fac, Ek, Dk)
        np.testing.assert_allclose(reduced.Sc, got.Sc, rtol=1e-12)
        cols = reduced.new_columns(2)
        cols[:] = np.moveaxis(b, 2, 0)
        dtheta = reduced.solve_columns(cols, c[keep])
        np.testing.assert_allclose(dtheta, ref[-keep.sum() :], atol=1e-10)
    # kept, only the right-hand sides were solved: 2 columns each time
    # (else [b, E] together, E alone for the score tests' border, then b)
    assert solved == ([2 + 3, 3, 2, 2 + 2, 2, 2] if offsets else [2, 2, 2, 2])
    # the first solve's Sc is the same numbers as a fresh elimination's
    fresh = BandedKKT(N, n).factor(Q, A, S)
    np.testing.assert_array_equal(
        kkt.solve_reduced(fresh, border, D, b, c).Sc, first.Sc
    )
    # a dense border is never kept (its identity says nothing of its values)
    other = BandedKKT(N, n).factor(Q, A, S)
    kkt.solve_reduced(other, E, D, b, c, keep_border=True)
    assert other.border is None


def test_a_converged_fit_keeps_its_border_and_an_unfinished_step_does_not(
    record, monkeypatch
):
    # The last Gauss-Newton step of a converged fit keeps K^-1 E with its
    # factor: the covariance then solves only the initial state's columns
    # and the score tests only the candidates' (the same numbers as with
    # the border solved again). A step that is not the last drops it before
    # the line search and the next linearisation.
    engine, data = record
    slots = [(1, 1), (1, 2), (1, 7)]
    smoother = type(engine._solver(slots, np.zeros(3), 1, 1e-9))
    linearize = smoother.linearize
    borders = []  # the kept factor's border at each later linearisation

    def watching(self, *args, **kwargs):
        with kkt._KEPT_LOCK:
            kept = kkt._KEPT[0][1] if kkt._KEPT else None
        if kept is not None:
            borders.append(kept.border)
        return linearize(self, *args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(smoother, "linearize", watching)
        unfinished = engine.fit(slots, np.array([-0.5, 0.5, -0.5]), data.x, max_iter=3)
    assert not unfinished.converged
    assert len(borders) >= 2 and all(b is None for b in borders)
    fit = engine.fit(slots, np.array([-1.0, 1.0, -1.0]), data.x, tol=1e-9)
    assert fit.converged
    solver, res = fit._state
    fac = solver.kkt_system(res._lin)[0]
    assert fac.border is not None
    widths = []
    solve = kkt.KKTFactor.solve_in_place

    def counting(self, cols):
        widths.append(cols.shape[1])
        return solve(self, cols)

    monkeypatch.setattr(kkt.KKTFactor, "solve_in_place", counting)
    cov = fit.covariance.copy()
    pool = [(1, c) for c in (0, 3, 9)]
    scores = engine.scores(fit, pool)
    assert widths == [2, 3]  # the initial state's columns; the candidates'
    kkt.drop_kept_border()
    fit._cov = None
    np.testing.assert_allclose(fit.covariance, cov, rtol=1e-12, atol=0)
    np.testing.assert_allclose(engine.scores(fit, pool)[0], scores[0], rtol=1e-10)
    # a fit that releases its linearisation releases the border with it
    again = engine.fit(slots, np.array([-1.0, 1.0, -1.0]), data.x, tol=1e-9)
    solver, res = again._state
    fac = solver.kkt_system(res._lin)[0]
    assert fac.border is not None
    del solver, res
    again.keep_statistics()
    # at once (by reference counting), not at the next garbage collection
    assert fac.border is None
