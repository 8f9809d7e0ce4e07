"""Results as objects: a Discovery that shows, keeps, travels and exports.

``summary()`` in statsmodels' style (text, HTML for a notebook, LaTeX),
data frames of the terms, parameters and gain, ``save``/``load`` through a
file that holds no pickle, ``pickle`` of the result itself, and the
extended model as sympy expressions and as Python source that simulates
without pysindy-mme. The studies are ~1 s Duffing cases
(``results_case.py``), run once per module.
"""

from __future__ import annotations

import ast
import json
import math
import pickle
import types
import warnings
from html.parser import HTMLParser

import numpy as np
import pytest
import results_case

from pysindy_mme import Discovery, ExtendedModel, NotSavedError
from pysindy_mme.core.tables import sig
from pysindy_mme.discovery.result import SavedDiscovery
from pysindy_mme.discovery.storage import FORMAT, VERSION
from pysindy_mme.discovery.summary import records


@pytest.fixture(scope="module")
def plain():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return results_case.study()


@pytest.fixture(scope="module")
def grey():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return results_case.study(grey=True)


@pytest.fixture(scope="module", params=["plain", "grey"])
def saved(request, tmp_path_factory):
    """``(original, loaded, path)``: the study saved and loaded back."""
    res = request.getfixturevalue(request.param)
    path = tmp_path_factory.mktemp("saved") / f"{request.param}.npz"
    res.save(path)
    return res, Discovery.load(path), path


# ------------------------------------------------------------ helpers
class _Tables(HTMLParser):
    """The ``<table>``s of an HTML text: caption, header, rows of cell text."""

    def __init__(self):
        super().__init__()
        self.tables, self._cell, self._row = [], None, None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append({"caption": "", "header": [], "rows": []})
        elif tag in ("th", "td", "caption"):
            self._cell = []
        elif tag == "tr":
            self._row = []

    def handle_endtag(self, tag):
        table = self.tables[-1] if self.tables else None
        if tag == "caption":
            table["caption"] = "".join(self._cell)
        elif tag in ("th", "td"):
            self._row.append(("th" if tag == "th" else "td", "".join(self._cell)))
        elif tag == "tr":
            if all(kind == "th" for kind, _ in self._row):
                table["header"] = [text for _, text in self._row]
            else:
                table["rows"].append([text for _, text in self._row])
        if tag in ("th", "td", "caption"):
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def html_tables(text) -> dict:
    parser = _Tables()
    parser.feed(text)
    return {t["caption"]: t for t in parser.tables}


def same_values(a, b) -> bool:
    """Equal, NaN equal to NaN, through lists, dicts and arrays."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same_values(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same_values(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    return a == b


def figure_data(fig) -> list:
    """Every plotted array and text of a figure, axes by axes."""
    import matplotlib

    out = []
    for ax in fig.findobj(matplotlib.axes.Axes):
        out.append(("title", ax.get_title(), [t.get_text() for t in ax.texts]))
        out.append(("ticks", [t.get_text() for t in ax.get_yticklabels()]))
        for line in ax.get_lines():
            out.append(("line", line.get_label(), line.get_xdata(), line.get_ydata()))
        for c in ax.collections:
            out.append(("points", c.get_label(), np.asarray(c.get_offsets())))
        for p in ax.patches:
            out.append(("patch", p.get_label(), np.asarray(p.get_bbox().bounds)))
    return out


# ------------------------------------------------------------ summary
def test_notebook_shows_the_summary_tables(plain):
    """What Jupyter renders (``_repr_html_``) holds the study's tables."""
    html_text = plain._repr_html_()
    tables = html_tables(html_text)
    assert {
        "Study",
        "Identified terms (95% CI)",
        "Gain: free-run RMSE",
        "Model error d(t) (MME)",
    } <= set(tables)
    study = {row[0]: row[1] for row in tables["Study"]["rows"]}
    assert study["conclusion"] == plain.conclusion
    assert study["states"] == "x1, x2" and study["measured"] == "x1"
    terms = tables["Identified terms (95% CI)"]
    assert terms["header"][:4] == ["eq.", "term", "coef", "std err"]
    (te,) = plain.term_estimates
    assert terms["rows"] == [
        [
            "x2",
            "x1^3",
            sig(te.coefficient),
            sig(te.std_error),
            sig(te.ci_low),
            sig(te.ci_high),
            *terms["rows"][0][6:],
        ]
    ]
    gain = tables["Gain: free-run RMSE"]
    g = plain.gain
    assert gain["rows"][0][:3] == [
        "x1",
        sig(g.rmse_assumed[0]),
        sig(g.rmse_extended[0]),
    ]
    assert gain["rows"][0][3] == f"{sig(g.ratio[0], 3)}x"
    assert "-1.008 x1^3" in html_text  # the extended model, among the notes


def test_summary_text_and_latex_show_the_same_tables(plain):
    summary = plain.summary()
    text = str(summary)
    assert text.startswith("pysindy-mme discovery")
    assert f"conclusion           {plain.conclusion}" in text
    assert "x2   x1^3  -1.008" in text
    latex = summary.as_latex()
    assert latex.count("\\begin{tabular}") == len(summary.tables)
    assert "\\caption{Identified terms (95\\% CI)}" in latex
    assert "x1\\textasciicircum{}3" in latex
    assert summary.table("Gain: free-run RMSE").rows[0][0] == "x1"
    assert str(plain).startswith("pysindy-mme discovery report")  # unchanged


def test_frames_of_terms_parameters_and_gain(grey):
    pd = pytest.importorskip("pandas")
    terms = grey.to_frame("terms")
    assert isinstance(terms, pd.DataFrame)
    assert list(terms.index) == [("x2", "x1^3")]
    assert terms.loc[("x2", "x1^3"), "coefficient"] == grey.terms["x2"]["x1^3"]
    assert {"std_error", "ci_low", "ci_high", "p_value"} <= set(terms.columns)
    params = grey.to_frame("parameters")
    assert list(params.index) == ["k"]
    assert params.loc["k", "value"] == grey.parameters["k"].value
    assert params.loc["k", "change"] == grey.parameters["k"].change
    gain = grey.to_frame("gain")
    assert gain.loc["x1", "gain"] == grey.gain.ratio[0]
    assert gain.loc["x1", "rmse_assumed"] == grey.gain.rmse_assumed[0]
    table = grey.summary().table("Parameters of the assumed model").to_frame()
    assert table["parameter"].tolist() == ["k"]
    with pytest.raises(ValueError, match="table must be one of"):
        grey.to_frame("coefficients")


def test_a_study_without_terms_has_empty_tables_with_their_columns():
    pd = pytest.importorskip("pandas")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = results_case.study(model=results_case.duffing_true)
    assert res.conclusion == "consistent"
    tables = html_tables(res._repr_html_())
    assert tables["Identified terms (95% CI)"]["rows"] == []
    terms = res.to_frame("terms")
    assert isinstance(terms, pd.DataFrame) and terms.empty
    assert list(terms.index.names) == ["state", "feature"]
    assert "coefficient" in terms.columns
    assert list(res.to_frame("parameters").columns)[:3] == [
        "initial",
        "assumed_fit",
        "value",
    ]


def test_optional_dependencies_missing_say_how_to_install(plain, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas fails
    monkeypatch.setitem(sys.modules, "sympy", None)
    with pytest.raises(ImportError, match=r"pysindy-mme\[pandas\]"):
        plain.to_frame("terms")
    with pytest.raises(ImportError, match=r"pysindy-mme\[sympy\]"):
        plain.extended_model.to_sympy()


# ---------------------------------------------------------- save / load
def test_save_load_reproduces_report_summary_and_tables(saved):
    res, back, _ = saved
    assert isinstance(back, SavedDiscovery) and isinstance(back, Discovery)
    assert str(back) == str(res)
    assert str(back.summary()) == str(res.summary())
    assert back._repr_html_() == res._repr_html_()
    assert back.summary().as_latex() == res.summary().as_latex()
    assert back.terms == res.terms
    for table in ("terms", "parameters", "gain"):
        assert same_values(records(back, table), records(res, table)), table
    assert same_values(
        {k: vars(v) for k, v in back.parameters.items()},
        {k: vars(v) for k, v in res.parameters.items()},
    )
    assert json.dumps(back.to_dict(), sort_keys=True) == json.dumps(
        res.to_dict(), sort_keys=True
    )
    assert back.extended_model.equations() == res.extended_model.equations()
    assert same_values(back.gain.in_sample_runs["extended"].x, res.extended_simulation)


def test_save_load_reproduces_the_plot(saved):
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    res, back, _ = saved
    before, after = res.plot(), back.plot()
    try:
        a, b = figure_data(before), figure_data(after)
        assert len(a) == len(b) > 20
        assert same_values(a, b)
    finally:
        plt.close(before)
        plt.close(after)


def test_saved_file_is_data_without_pickle(saved):
    res, _, path = saved
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data["__meta__"]))
        arrays = {k: data[k] for k in data.files}  # every entry reads as data
    assert meta["format"] == FORMAT and meta["version"] == VERSION
    assert meta["report"] == str(res)
    assert all(a.dtype != object for a in arrays.values())
    assert np.array_equal(arrays["study.y"], res.y, equal_nan=True)


def test_a_newer_format_is_refused(saved, tmp_path):
    _, _, path = saved
    with np.load(path, allow_pickle=False) as data:
        entries = {k: data[k] for k in data.files}
    meta = json.loads(str(entries.pop("__meta__")))
    meta["version"] = VERSION + 1
    newer = tmp_path / "newer.npz"
    np.savez(newer, __meta__=np.array(json.dumps(meta)), **entries)
    with pytest.raises(ValueError, match="upgrade pysindy-mme"):
        Discovery.load(newer)
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(ValueError, match="not a saved pysindy-mme discovery"):
        Discovery.load(tmp_path / "other.npz")


def test_a_version_1_file_reads_without_the_kink_misfit(saved, tmp_path):
    # version 2 added fields.kink_misfit; a file written before it loads with
    # None there and everything else as saved
    res, _, path = saved
    assert res.kink_misfit is None  # no smoothed kinks in these studies
    with np.load(path, allow_pickle=False) as data:
        entries = {k: data[k] for k in data.files}
    meta = json.loads(str(entries.pop("__meta__")))
    assert "kink_misfit" in meta["result"]["fields"]
    del meta["result"]["fields"]["kink_misfit"]
    meta["version"] = 1
    older = tmp_path / "older.npz"
    np.savez(older, __meta__=np.array(json.dumps(meta)), **entries)
    back = Discovery.load(older)
    assert back.kink_misfit is None
    assert str(back) == str(res)


def test_a_version_2_file_reads_with_no_run_set_by_rounding(saved, tmp_path):
    # version 3 added gain.rounding_set (tests/discovery/test_rounding_set_runs.py)
    res, _, path = saved
    with np.load(path, allow_pickle=False) as data:
        entries = {k: data[k] for k in data.files}
    meta = json.loads(str(entries.pop("__meta__")))
    gain = meta["result"]["gain"]["fields"]
    assert gain.pop("rounding_set") == {}
    meta["version"] = 2
    older = tmp_path / "older.npz"
    np.savez(older, __meta__=np.array(json.dumps(meta)), **entries)
    back = Discovery.load(older)
    assert back.gain.rounding_set == {}
    assert str(back) == str(res)


def _without(value, key):
    """``value`` (a saved file's JSON) with every ``key`` entry of a
    record's fields removed."""
    if isinstance(value, dict):
        return {k: _without(v, key) for k, v in value.items() if k != key}
    if isinstance(value, list):
        return [_without(v, key) for v in value]
    return value


def test_a_version_3_file_reads_with_every_run_determined(saved, tmp_path):
    # version 4 added each free run's determined_until
    # (tests/protocols/test_run_spread.py); these records' held-out runs
    # have one, and the report marks it
    res, _, path = saved
    runs = res.gain.validation_runs
    assert any(r.determined_until is not None for r in runs.values())
    assert "SPREAD BY ITS START" in str(res)
    with np.load(path, allow_pickle=False) as data:
        entries = {k: data[k] for k in data.files}
    meta = json.loads(str(entries.pop("__meta__")))
    meta = _without(meta, "determined_until")
    meta["version"] = 3
    older = tmp_path / "older.npz"
    np.savez(older, __meta__=np.array(json.dumps(meta)), **entries)
    back = Discovery.load(older)
    assert all(r.determined_until is None for r in back.gain.validation_runs.values())
    assert "SPREAD BY ITS START" not in str(back)
    assert back.terms == res.terms
    np.testing.assert_array_equal(
        back.gain.validation_rmse_extended, res.gain.validation_rmse_extended
    )


def test_loaded_result_names_what_was_not_saved(saved):
    res, back, _ = saved
    x0 = res.extended_simulation[0]
    with pytest.raises(NotSavedError, match="assumed_model=f"):
        back.extended_model.simulate(x0, res.t, method="rk4")
    with pytest.raises(NotSavedError, match="validate"):
        back.validate(res.y, res.t)
    with pytest.raises(NotSavedError, match="MME estimator"):
        back.mme.fit  # noqa: B018
    assert not hasattr(back.optimizer, "coef_")  # absent, as getattr sees it
    # a correction of products of powers evaluates from the stored names
    assert np.array_equal(
        back.extended_model.correction(res.extended_simulation),
        res.extended_model.correction(res.extended_simulation),
    )


def test_loaded_with_the_assumed_model_simulates_as_before(saved):
    res, _, path = saved
    model = (
        results_case.duffing_grey if res.parameters else results_case.duffing_assumed
    )
    back = Discovery.load(path, assumed_model=model)
    x0 = res.extended_simulation[0]
    before = res.extended_model.simulate(x0, res.t, method="rk4")
    after = back.extended_model.simulate(x0, res.t, method="rk4")
    assert np.array_equal(before, after)


# -------------------------------------------------------------- pickle
def test_pickle_round_trip(plain):
    back = pickle.loads(pickle.dumps(plain))
    assert str(back) == str(plain)
    x0 = plain.extended_simulation[0]
    assert np.array_equal(
        back.extended_model.simulate(x0, plain.t, method="rk4"),
        plain.extended_model.simulate(x0, plain.t, method="rk4"),
    )
    again = pickle.loads(pickle.dumps(back))  # and the unpickled one pickles
    assert again.terms == plain.terms


def test_pickle_of_a_loaded_result(saved):
    _, back, _ = saved
    assert str(pickle.loads(pickle.dumps(back))) == str(back)


# -------------------------------------------------------------- export
def _exported(model) -> types.ModuleType:
    source = model.to_python()
    module = types.ModuleType("exported_model")
    exec(compile(source, "exported_model.py", "exec"), module.__dict__)
    return module


@pytest.mark.parametrize("case", ["plain", "grey"])
def test_exported_python_simulates_like_the_extended_model(case, request):
    res = request.getfixturevalue(case)
    model = res.extended_model
    source = model.to_python()
    imports = {
        alias.name
        for node in ast.walk(ast.parse(source))
        if isinstance(node, (ast.Import, ast.ImportFrom))
        for alias in node.names
    }
    assert imports == {"numpy", "inspect"}  # no pysindy-mme, no pysindy
    exported = _exported(model)
    user = results_case.duffing_grey if case == "grey" else results_case.duffing_assumed
    x0 = res.extended_simulation[0]
    reference = model.simulate(x0, res.t, method="rk4")
    ours = exported.simulate(user, x0, res.t)
    assert np.max(np.abs(ours - reference)) <= 1e-9
    x = res.extended_simulation
    assert np.allclose(exported.correction(x), model.correction(x), rtol=1e-14)
    if case == "grey":
        assert exported.PARAMETERS == {"k": res.parameters["k"].value}


def test_exported_python_of_a_model_with_inputs_and_a_constant():
    """Inputs (linear hold between samples) and an intercept, to 1e-9."""
    import pysindy as ps

    t = np.linspace(0.0, 5.0, 101)
    u = np.sin(3 * t)[:, None]
    z = np.random.default_rng(1).normal(size=(50, 2))
    library = ps.PolynomialLibrary(degree=2).fit(z)  # columns of (x0, u0)
    coef = np.zeros((1, library.n_output_features_))
    names = library.get_feature_names(["x0", "u0"])
    coef[0, names.index("x0 u0")] = 0.7
    coef[0, names.index("1")] = -0.2
    model = ExtendedModel(
        results_case_decay, library, coef, ["x0"], ["u0"], intercept=[0.05]
    )
    reference = model.simulate([1.0], t, u=u, method="rk4", substeps=3)
    exported = _exported(model)
    ours = exported.simulate(results_case_decay, [1.0], t, u=u, substeps=3)
    assert np.max(np.abs(ours - reference)) <= 1e-9


def results_case_decay(x, t, u):
    return -x + u


def test_to_python_refuses_library_code_and_names_it():
    import pysindy as ps

    library = ps.CustomLibrary(
        library_functions=[lambda a: np.sin(a)],
        function_names=[lambda a: f"sin({a})"],
    ).fit(np.zeros((5, 2)))
    model = ExtendedModel(
        results_case.duffing_assumed, library, [[0, 0], [0.5, 0]], ["x1", "x2"]
    )
    with pytest.raises(ValueError, match=r"\['sin\(x1\)'\]"):
        model.to_python()
    sympy = pytest.importorskip("sympy")
    x1, x2, t = sympy.symbols("x1 x2 t")
    rhs = model.to_sympy()
    assert rhs[1] == sympy.Function("f_x2")(x1, x2, t) + sympy.Float(0.5) * sympy.sin(
        x1
    )


def test_to_sympy_gives_the_correction_exactly(plain):
    sympy = pytest.importorskip("sympy")
    x1, x2, t = sympy.symbols("x1 x2 t")
    rhs = plain.extended_model.to_sympy()
    coef = plain.terms["x2"]["x1^3"]
    assert rhs[0] == sympy.Function("f_x1")(x1, x2, t)
    assert rhs[1] == sympy.Function("f_x2")(x1, x2, t) + sympy.Float(coef) * x1**3
    correction = rhs[1] - sympy.Function("f_x2")(x1, x2, t)
    assert float(correction.subs({x1: 1.3, x2: 0.2})) == pytest.approx(
        plain.extended_model.correction([[1.3, 0.2]])[0, 1], rel=1e-15
    )
    with_text = ExtendedModel(
        results_case.duffing_assumed,
        plain.extended_model.feature_library,
        plain.extended_model.correction_coef_,
        ["x1", "x2"],
        assumed_equations=["x2", "-x1 - 0.1 x2"],
    )
    rhs = with_text.to_sympy()
    assert rhs[0] == x2
    assert sympy.simplify(rhs[1] - (-x1 - sympy.Float(0.1) * x2 + coef * x1**3)) == 0


def test_one_state_model_answering_a_flat_array_pickles_and_saves(tmp_path):
    """A one-state model may return ``(n_rows,)``; the study takes it as a
    column and its result pickles and round-trips."""
    import pysindy as ps

    from pysindy_mme import discover

    t = np.linspace(0.0, 5.0, 200)
    rng = np.random.default_rng(0)
    y = 2.0 * np.exp(-1.3 * t)[:, None] + 0.01 * rng.normal(size=(200, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = discover(
            y,
            t,
            assumed_model=results_case.decay,
            n_states=1,
            noise_variance=1e-4,
            feature_library=ps.PolynomialLibrary(degree=2),
        )
    assert list(res.terms["x0"]) == ["x0"]
    assert str(pickle.loads(pickle.dumps(res))) == str(res)
    res.save(tmp_path / "decay.npz")
    assert str(Discovery.load(tmp_path / "decay.npz")) == str(res)


# ---------------------------------------------------------- command line
def test_command_line_output_folder_holds_the_reloadable_result(plain, tmp_path):
    pytest.importorskip("matplotlib")
    from pysindy_mme.cli.outputs import write_outputs

    written = write_outputs(plain, tmp_path)
    assert tmp_path / "discovery.npz" in written
    assert str(Discovery.load(tmp_path / "discovery.npz")) == str(plain)


@pytest.mark.parametrize("case", ["plain", "grey"])
def test_a_result_keeps_statistics_not_linearisations(case, request):
    """The fits a Discovery returns hold their numbers, not their solvers:
    a study's linearisations (flows, sensitivities, about 300 bytes per
    sample) are released before the gain stage, so a list of results (many
    records, ``discover_many``) costs their numbers only."""
    res = request.getfixturevalue(case)
    for fit in (res.assumed.fit, res.extended_fit):
        assert fit._state is None
        cov = fit.covariance
        k = fit.theta.size
        assert cov.shape == (k, k)
        assert np.all(np.isfinite(np.diag(cov)[~fit.held]))
        assert np.all(np.isfinite(fit.x0_covariance))
    # the report's standard errors are those numbers
    se = res.extended_fit.std_errors
    assert np.all(np.isfinite(se[~res.extended_fit.held]))
