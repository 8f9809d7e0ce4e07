"""The figures show what they claim, in a way a reader takes in at a glance.

Checked on the drawn matplotlib objects: the extended model is the line on
top, legends lie outside every data area, the gain bars have the report's
heights, the step-history labels never overlap.
"""

import warnings
from types import SimpleNamespace

import numpy as np
import pysindy as ps
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

from paper_case import DATA, VDP, paper_discover  # noqa: E402

from pysindy_mme import PowerLibrary  # noqa: E402
from pysindy_mme.core.tables import sig  # noqa: E402
from pysindy_mme.discovery.gain import Gain  # noqa: E402
from pysindy_mme.optimizers.selection import Step  # noqa: E402
from pysindy_mme.plotting import (  # noqa: E402
    gain_figure,
    history_figure,
    model_error_figure,
    plot_gain,
    save_figures,
    states_figure,
)
from pysindy_mme.plotting._base import LABEL, pyplot  # noqa: E402


@pytest.fixture(scope="module")
def study():
    check = VDP.measure(1, x0=(2.0, -1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = paper_discover(
            feature_library=ps.PolynomialLibrary(degree=3),
            validation=(check.y, check.t),
        )
    return res, DATA


@pytest.fixture(autouse=True)
def close_figures():
    yield
    pyplot().close("all")


def _extent(artist, fig):
    fig.canvas.draw()
    return artist.get_window_extent(fig.canvas.get_renderer())


def _overlap(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def test_save_figures_writes_the_four_views(study, tmp_path):
    res, data = study
    paths = save_figures(res, tmp_path, x_true=data.x, d_true=data.d)
    assert [p.name for p in paths] == [
        "states.png",
        "model_error.png",
        "gain.png",
        "stepwise_history.png",
    ]
    image = pyplot().imread(paths[2])
    assert image.shape[0] > 300 and image.shape[1] > 700  # readable, not a thumbnail
    for p in paths:
        assert p.stat().st_size > 10_000


def test_extended_model_is_the_line_on_top_in_its_own_style(study):
    res, data = study
    fig = states_figure(res, x_true=data.x)
    for i, ax in enumerate(fig.axes[: len(res.state_names)]):
        lines = {line.get_label(): line for line in ax.get_lines()}
        ext = lines[LABEL["extended"]]
        assumed = next(v for k, v in lines.items() if k.startswith(LABEL["assumed"]))
        assert ext.get_zorder() == max(line.get_zorder() for line in ax.get_lines())
        assert ext.get_linestyle() == "-" and assumed.get_linestyle() != "-"
        assert ext.get_color() != assumed.get_color()
        assert ext.get_linewidth() > max(
            line.get_linewidth() for line in ax.get_lines() if line is not ext
        )
        np.testing.assert_array_equal(ext.get_ydata(), res.extended_simulation[:, i])


def test_legends_lie_outside_every_data_area(study):
    res, data = study
    for fig in (
        states_figure(res, x_true=data.x),
        model_error_figure(res, d_true=data.d),
        gain_figure(res),
        history_figure(res),
    ):
        legends = fig.legends + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
        assert legends, "every figure explains its lines"
        for legend in legends:
            box = _extent(legend, fig)
            for ax in fig.axes:
                assert not _overlap(box, _extent(ax.patch, fig)), (fig, ax)


def test_model_error_panel_shows_the_identified_correction(study):
    res, data = study
    fig = model_error_figure(res, d_true=data.d)
    lines = {line.get_label(): line for line in fig.axes[0].get_lines()}
    expected = res.extended_model.correction(res.extended_simulation, res.u)[:, 1]
    np.testing.assert_allclose(lines[LABEL["correction"]].get_ydata(), expected)
    np.testing.assert_array_equal(
        lines["MME estimate d(t)"].get_ydata(), res.mme.d_[:, 1]
    )
    # The largest peak of d(t) is inside the axes' view, not clipped.
    lo, hi = fig.axes[0].get_ylim()
    assert lo < np.min(data.d[:, 1]) and np.max(data.d[:, 1]) < hi


def test_gain_panel_has_the_reports_numbers(study):
    res, _ = study
    fig = gain_figure(res)
    ax = fig.axes[0]
    g = res.gain
    values = np.array(
        [
            g.rmse_assumed[0],
            g.rmse_extended[0],
            g.validation_rmse_assumed[0],
            g.validation_rmse_extended[0],
        ]
    )
    solid = [p for p in ax.patches if not p.get_hatch()]
    heights = sorted(p.get_height() for p in solid)
    finite = np.isfinite(values)
    np.testing.assert_allclose(heights, np.sort(values[finite]), rtol=1e-12)
    texts = [t.get_text() for t in ax.texts]
    assert texts.count("diverged") == int(np.sum(~finite))
    for ratio in (g.ratio[0], g.validation_ratio[0]):
        label = f"gain {sig(ratio, 3)}x" if np.isfinite(ratio) else "gain n/a"
        assert label in texts
    floors = [c for c in ax.collections if c.get_label().startswith("noise floor")]
    segments = np.concatenate([c.get_segments() for c in floors])
    np.testing.assert_allclose(segments[:, :, 1], g.noise_floor[0])
    labels = [t.get_text() for t in ax.get_xticklabels()]
    assert labels == ["x1\nin-sample", "x1\nvalidation"]


def test_gain_panel_marks_a_diverged_model_instead_of_a_number():
    gain = Gain(
        channel_names=["a", "b"],
        rmse_assumed=np.array([1.0, 2.0]),
        rmse_extended=np.array([0.1, 0.2]),
        noise_floor=np.array([0.1, 0.15]),
        validation_rmse_assumed=np.array([1.5, 2.5]),
        validation_rmse_extended=np.array([np.inf, 0.3]),
        validation_window=50,
    )
    fig, ax = pyplot().subplots()
    plot_gain(gain, ax)
    texts = [t.get_text() for t in ax.texts]
    assert texts.count("diverged") == 1
    assert "gain n/a" in texts and "gain 10x" in texts
    hatched = [p for p in ax.patches if p.get_hatch()]
    assert len(hatched) == 1


@pytest.mark.filterwarnings("error::UserWarning")  # e.g. a collapsed layout
def test_history_rows_never_overlap_even_for_a_long_history():
    """45 steps with the long names of the paper's Table I library."""
    names = PowerLibrary().fit(np.ones((3, 2))).get_feature_names(["x1", "x2"])
    rng = np.random.default_rng(0)
    picks = rng.choice(len(names), size=45)
    steps, model = [], []
    for k, j in enumerate(picks, start=1):
        action = "remove" if names[j] in model else "add"
        model = (
            model + [names[j]]
            if action == "add"
            else [n for n in model if n != names[j]]
        )
        steps.append(
            Step(
                iteration=k,
                phase=1 if k < 30 else 2,
                action=action,
                feature=int(j),
                name=f"f{j}",
                partial_f=float(10 ** rng.uniform(0, 3)),
                threshold=10.0 if k < 30 else 300.0,
                n_terms=len(model),
            )
        )
    res = SimpleNamespace(
        optimizer=SimpleNamespace(steps_=[steps]),
        error_states=[1],
        state_names=["x1", "x2"],
        library_feature_names=names,
    )
    fig = history_figure(res)
    ax = fig.axes[0]
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    labels = [t for t in ax.get_yticklabels() if t.get_text()]
    assert len(labels) == len(steps)
    assert labels[0].get_text() == f"1. add {names[picks[0]]}"
    boxes = sorted((t.get_window_extent(renderer) for t in labels), key=lambda b: b.y0)
    for lower, upper in zip(boxes, boxes[1:]):
        assert lower.y1 <= upper.y0 + 0.5, "labels overlap"
    plot_area = ax.patch.get_window_extent(renderer)
    assert all(b.x1 <= plot_area.x0 + 0.5 for b in boxes)
    # The title names the final model, in order of entry: the first ten
    # terms and how many more.
    final = " ".join(ax.get_title(loc="left").split("final model: ")[1].split())
    assert len(model) > 10
    assert final == ", ".join(model[:10]) + f" and {len(model) - 10} more"


def test_measurements_are_drawn_on_the_states_scale_when_offsets_were_fitted(study):
    res, _ = study

    class WithOffset:
        """The study as if discover(..., offsets=True) had fitted 0.5."""

        offsets = np.array([0.5])

        def __getattr__(self, name):
            return getattr(res, name)

    fig = states_figure(WithOffset())
    lines = {line.get_label(): line for line in fig.axes[0].get_lines()}
    np.testing.assert_allclose(
        lines["measured - fitted offset"].get_ydata(), res.y[:, 0] - 0.5
    )
