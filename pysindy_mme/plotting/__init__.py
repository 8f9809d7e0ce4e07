"""Figures of a discovery study (matplotlib is an optional dependency).

Four views, after the paper's Figs. 2-4 plus the gain: the states
(measurements, MME estimate, assumed and extended simulations), the model
error ``d(t)`` against the identified correction, the gain (simulation RMSE
per channel, assumed vs extended vs the noise floor), and the stepwise
history. ``Discovery.plot`` draws them all in one figure;
:func:`save_figures` writes one PNG per view (what ``pysindy-mme`` does).
"""

from ._base import pyplot
from .figures import (
    gain_figure,
    history_figure,
    model_error_figure,
    plot_discovery,
    save_figures,
    states_figure,
)
from .gain import plot_gain
from .history import plot_stepwise_history
from .model_error import plot_model_error
from .states import plot_states

_pyplot = pyplot  # the name the command line used before the package split

__all__ = [
    "plot_discovery",
    "plot_states",
    "plot_model_error",
    "plot_gain",
    "plot_stepwise_history",
    "save_figures",
    "states_figure",
    "model_error_figure",
    "gain_figure",
    "history_figure",
]
