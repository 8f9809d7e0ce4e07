"""SelectedFeatures: library columns evaluated fast, against pysindy's transform."""

import numpy as np
import pysindy as ps

from pysindy_mme.core.features import SelectedFeatures


def test_selected_features_fast_path_matches_transform():
    rng = np.random.default_rng(1)
    z = rng.normal(size=(50, 3))
    lib = ps.PolynomialLibrary(degree=3).fit(z)
    cols = [0, 4, 9, 15, 19]
    sel = SelectedFeatures(lib, ["a", "b", "c"], cols, z)
    assert sel.is_fast
    np.testing.assert_allclose(sel(z), np.asarray(lib.transform(z))[:, cols])


def test_selected_features_falls_back_for_unparseable_names():
    rng = np.random.default_rng(2)
    z = rng.normal(size=(40, 2))
    lib = ps.FourierLibrary(n_frequencies=2).fit(z)
    sel = SelectedFeatures(lib, ["a", "b"], [0, 3], z)
    assert not sel.is_fast
    np.testing.assert_allclose(sel(z), np.asarray(lib.transform(z))[:, [0, 3]])


def test_the_fast_path_is_checked_on_every_row_block(monkeypatch):
    """The check against transform runs by blocks of rows (a long record's
    library is not held several times over); a disagreement in the last
    block alone still sends the columns to the slow path."""
    from pysindy_mme.core import features

    monkeypatch.setattr(features, "_CHECK_ROWS", 16)
    rng = np.random.default_rng(3)
    z = rng.normal(size=(100, 2))
    lib = ps.PolynomialLibrary(degree=2).fit(z)
    sel = SelectedFeatures(lib, ["a", "b"], [1, 4], z)
    assert sel.is_fast

    class Odd(ps.PolynomialLibrary):
        # x0^2 as transform computes it differs from the product at one row
        def transform(self, x):
            out = np.asarray(super().transform(x)).copy()
            out[x[:, 0] == 3.0, 3] += 1.0
            return out

    z[95, 0] = 3.0
    odd = Odd(degree=2).fit(z)
    assert not SelectedFeatures(odd, ["a", "b"], [1, 3], z).is_fast
    assert SelectedFeatures(odd, ["a", "b"], [1, 3], z[:90]).is_fast


def test_the_fast_path_check_holds_about_one_library_block():
    import tracemalloc

    rng = np.random.default_rng(4)
    z = rng.normal(size=(800_000, 2))
    lib = ps.PolynomialLibrary(degree=3).fit(z[:100])
    library = z.shape[0] * 10 * 8  # bytes of the whole library's values
    tracemalloc.start()
    try:
        sel = SelectedFeatures(lib, ["a", "b"], list(range(10)), z)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert sel.is_fast
    # blocks of rows: a fraction of the library (the check on all rows at
    # once held about six copies of it)
    assert peak < 0.5 * library, peak / library
