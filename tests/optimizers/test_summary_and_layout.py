"""The summary object, the old import paths, and the size rules of the package."""

from __future__ import annotations

import ast
import pickle
from pathlib import Path

import numpy as np
import pytest

import pysindy_mme.optimizers as optimizers
from pysindy_mme.optimizers import FloatingFStepwise, StepwiseSummary

PACKAGE = Path(optimizers.__file__).parent
HALD = Path(__file__).resolve().parents[1] / "data" / "hald_cement.csv"


@pytest.fixture(scope="module")
def hald_fit():
    data = np.genfromtxt(HALD, delimiter=",", names=True)
    X = np.column_stack([data[f"x{i}"] for i in range(1, 5)])
    opt = FloatingFStepwise(f_enter=4, f_remove=4, floating=False)
    return opt.fit(X, data["y"], feature_names=["x1", "x2", "x3", "x4"])


def test_summary_is_the_text_with_html_and_tables(hald_fit):
    s = hald_fit.summary()
    assert isinstance(s, StepwiseSummary) and isinstance(s, str)
    assert type(str(s)) is str
    assert str(s) == s.as_text() == repr(s)
    # The text is the concatenation of the ANOVA table's own text and the
    # step history; the HTML carries the same numbers.
    title = s.splitlines()[2]
    assert title.startswith("=== target 0: final model ANOVA table (4 steps")
    assert hald_fit.anova_[0].to_text(["x1", "x2", "x3", "x4"], title=title) in s
    html = s._repr_html_()
    assert html == s.as_html()
    assert html.count("<table") == 5  # header, ANOVA, in, out, steps
    for phrase in ("Due to regression", "52.577", "229.5", "x4", "remove"):
        assert phrase in html
    assert s.tables == [hald_fit.anova_[0]]
    assert [st.feature for st in s.steps[0]] == [3, 0, 1, 3]
    again = pickle.loads(pickle.dumps(s))
    assert again == s and again.as_html() == html and isinstance(again, StepwiseSummary)


def test_html_escapes_names():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((60, 3))
    y = X[:, 0] + 0.1 * rng.standard_normal(60)
    opt = FloatingFStepwise().fit(X, y, feature_names=["a<b", "c&d", "e"])
    html = opt.summary()._repr_html_()
    assert "a&lt;b" in html and "a<b" not in html
    assert "a<b" in str(opt.summary())
    assert opt.anova_[0]._repr_html_().startswith("<table")


def test_old_import_paths_are_gone():
    """0.x removed the re-export shims: one real path per name (issue 22)."""
    import importlib

    for old in ("anova", "stepwise", "mme", "smoother", "libraries", "extended"):
        with pytest.raises(ModuleNotFoundError):
            importlib.import_module(f"pysindy_mme.{old}")


def _functions(tree):
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node


@pytest.mark.parametrize("path", sorted(PACKAGE.glob("*.py")), ids=lambda p: p.name)
def test_no_module_over_600_lines_no_function_over_120(path):
    text = path.read_text()
    assert len(text.splitlines()) <= 600, path.name
    for fn in _functions(ast.parse(text)):
        length = fn.end_lineno - fn.lineno + 1
        assert length <= 120, f"{path.name}: {fn.name} has {length} lines"
