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
