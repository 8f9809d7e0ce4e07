"""Old import path of the ANOVA statistics (now :mod:`pysindy_mme.optimizers.anova`).

Kept so that ``from pysindy_mme.anova import fit_anova, AnovaTable, ...`` keeps
working.
"""

from .optimizers.anova import (
    AnovaTable,
    f_critical,
    f_pvalue,
    fit_anova,
    lstsq_refined,
)

__all__ = [
    "AnovaTable",
    "fit_anova",
    "f_critical",
    "f_pvalue",
    "lstsq_refined",
]
