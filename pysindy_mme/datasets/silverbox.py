"""The Silverbox benchmark: an electronic oscillator with a nonlinear spring.

T. Wigren and J. Schoukens, "Three free data sets for development and
benchmarking in nonlinear system identification", 2013 European Control
Conference (ECC), Zurich, pp. 2933-2938 (Uppsala University technical
report 2013-006). The benchmark's page states no licence for the data: they
are downloaded by the user from the official source and never shipped with
this package.
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np
from sklearn.utils import Bunch

from ._base import fetch_zip_member, get_data_home, sha256_hex

__all__ = ["fetch_silverbox", "SilverboxData"]

# The benchmark page's download link points to this Google Drive file
# (SilverboxFiles.zip, 5,793,999 bytes); "uc?export=download" is Drive's
# direct-download form of it. The older address
# http://www.nonlinearbenchmark.org/FILES/BENCHMARKS/SILVERBOX/SilverboxFiles.zip
# no longer serves it. What is verified is the SHA-256 of the extracted CSV,
# which does not change when the archive is repacked or moved.
SILVERBOX_PAGE = "https://www.nonlinearbenchmark.org/benchmarks/silverbox"
SILVERBOX_URL = (
    "https://drive.google.com/uc?export=download&id=17iS-6oBUUgrmiAcrZoG9S5sOaljZnDSy"
)
SILVERBOX_CSV = "SNLS80mV.csv"
SILVERBOX_CSV_SHA256 = (
    "ae62d5a91230c10f76e6dd02c8a4fac3c9d4d8a95fbf50e87cb0c4885003e0f1"
)
SILVERBOX_FS = 610.35  # Hz

# Official splits: 0-based half-open sample ranges, as the benchmark's own
# loader (nonlinear_benchmarks.Silverbox) cuts them; training is the first
# 75 % of the multisine estimation block. Each test's first 50 samples may be
# used to settle the initial state and are not scored.
SPLITS = {
    "estimation": (40650, 127400),
    "train": (40650, 105712),
    "test_multisine": (105712, 127400),
    "test_arrow_full": (100, 40575),
    "test_arrow_no_extrapolation": (100, 32100),
}
N_INIT = {name: (50 if name.startswith("test") else 0) for name in SPLITS}

# Published simulation RMSE in mV on the test splits, (low, high) over the
# reported variants, None where not reported. The first two rows are the best
# published results on the arrow (its extrapolating end included), each under
# its authors' own estimation data and start-up, which need not be exactly the
# official splits here; the others as compiled with the data
# (shared/data/silverbox/README.md) from the benchmark's published results.
# Where each row comes from: BASELINE_SOURCES.
BASELINES_MV = {
    "polynomial nonlinear state space, PNLSS (Paduart et al. 2010)": {
        "test_arrow_full": (0.26, 0.26),
        "test_arrow_no_extrapolation": None,
        "test_multisine": None,
    },
    "nonlinear ARX (Silverbox benchmark results)": {
        "test_arrow_full": (0.30, 0.30),
        "test_arrow_no_extrapolation": None,
        "test_multisine": None,
    },
    "polynomial NARX (forward regression, tuned per split)": {
        "test_arrow_full": (4.15, 4.15),
        "test_arrow_no_extrapolation": (2.23, 2.23),
        "test_multisine": (7.73, 7.73),
    },
    "recurrent networks (GRU, LSTM)": {
        "test_arrow_full": (2.4, 2.8),
        "test_arrow_no_extrapolation": (0.95, 1.1),
        "test_multisine": (1.5, 1.5),
    },
    "neural state-space encoder": {
        "test_arrow_full": (5.8, 6.8),
        "test_arrow_no_extrapolation": (2.0, 2.2),
        "test_multisine": None,
    },
}

CITATION = (
    "T. Wigren and J. Schoukens, Three free data sets for development and "
    "benchmarking in nonlinear system identification, 2013 European Control "
    "Conference (ECC), Zurich, Switzerland, pp. 2933-2938, 2013."
)

BASELINE_SOURCES = {
    "polynomial nonlinear state space, PNLSS (Paduart et al. 2010)": (
        "J. Paduart, L. Lauwers, J. Swevers, K. Smolders, J. Schoukens and "
        "R. Pintelon, Identification of nonlinear systems using polynomial "
        "nonlinear state space models, Automatica 46(4), pp. 647-656, 2010: "
        "0.26 mV on the arrow, its extrapolating end included."
    ),
    "nonlinear ARX (Silverbox benchmark results)": (
        "a nonlinear ARX model among the Silverbox benchmark's published "
        "results, 0.30 mV on the arrow (the primary paper was not located "
        "for this table; benchmark: " + CITATION + ")"
    ),
    "polynomial NARX (forward regression, tuned per split)": (
        "as compiled with the data from the benchmark's published results"
    ),
    "recurrent networks (GRU, LSTM)": (
        "as compiled with the data from the benchmark's published results"
    ),
    "neural state-space encoder": (
        "as compiled with the data from the benchmark's published results"
    ),
}

DESCR = f"""Silverbox benchmark (Wigren and Schoukens, 2013)
-------------------------------------------------

An electronic circuit built to behave like a mass-spring-damper whose spring
is not linear, m y'' + d y' + k(y) y = u (a Duffing-like oscillator).

- u: input voltage V1 (the force), y: output voltage V2 (the displacement),
  in volts; 131,072 samples at fs = {SILVERBOX_FS} Hz; t in seconds from the
  first sample. The input was generated with a zero-order hold and low-pass
  filtered before it reached the circuit.
- Offsets: with remove_offset=True (the default) the record means are
  subtracted from u and y, as the benchmark's README does (an
  approximation: the circuit itself can create a small DC level); the
  subtracted values are in ``offsets``.
- Splits (``splits``, half-open sample ranges): estimation = the multisine
  block [40650, 127400); train = its first 75 % [40650, 105712);
  test_multisine = [105712, 127400); test_arrow_full = [100, 40575) (its
  amplitude grows past what training covers); test_arrow_no_extrapolation =
  [100, 32100). Each test's first 50 samples (``n_init``) may be used to
  settle the initial state; the score is the simulation RMSE in mV on the
  rest (``rmse_mv``).
- Published results on these splits, in mV: ``baselines_mv`` (where each
  comes from: ``baseline_sources``). The best on the arrow: a polynomial
  nonlinear state-space model, 0.26 mV (Paduart et al., Automatica 2010),
  and a nonlinear ARX model, 0.30 mV, each under its authors' protocol.
- The benchmark's page ({SILVERBOX_PAGE}) states no licence for the data:
  use them for development and tests, do not redistribute them.

Cite: {CITATION}
"""


class SilverboxData(Bunch):
    """The Bunch returned by :func:`fetch_silverbox`, with split helpers."""

    def split(self, name):
        """One official split as a Bunch with ``u``, ``y``, ``t`` (copies).

        Also ``name``, ``start``, ``stop`` (sample range in the record) and
        ``n_init`` (leading samples for settling the initial state, not
        scored). ``name`` is a key of ``splits``.
        """
        sl = self._slice(name)
        return Bunch(
            u=self["u"][sl].copy(),
            y=self["y"][sl].copy(),
            t=self["t"][sl].copy(),
            name=name,
            start=sl.start,
            stop=sl.stop,
            n_init=self["n_init"][name],
        )

    def rmse_mv(self, name, y_sim):
        """Simulation RMSE in mV on split ``name``, its first ``n_init`` left out.

        ``y_sim`` is the simulated output (volts) over the whole split, the
        same length as ``split(name).y``.
        """
        sl = self._slice(name)
        y = self["y"][sl]
        y_sim = np.asarray(y_sim, dtype=float).ravel()
        if y_sim.shape != y.shape:
            raise ValueError(
                f"y_sim has {y_sim.size} samples but split {name!r} has {y.size}"
            )
        k = self["n_init"][name]
        err = y_sim[k:] - y[k:]
        if not np.all(np.isfinite(err)):
            raise ValueError("y_sim contains NaN or inf")
        return float(1e3 * np.sqrt(np.mean(err**2)))

    def _slice(self, name):
        if name not in self["splits"]:
            raise ValueError(
                f"split must be one of {sorted(self['splits'])}, got {name!r}"
            )
        return self["splits"][name]


def fetch_silverbox(data_home=None, *, download_if_missing=True, remove_offset=True):
    """Load the Silverbox record (downloading it once if needed).

    Looks for ``SNLS80mV.csv`` in ``data_home`` and in ``data_home/silverbox``
    (so a folder that already holds the file works as is). A file found is
    checked against its known SHA-256 and read, without any network. Else,
    if ``download_if_missing``, the official archive is downloaded, the CSV
    taken out and verified, and only then saved as
    ``data_home/silverbox/SNLS80mV.csv``.

    Parameters
    ----------
    data_home : str, path or None
        See :func:`pysindy_mme.datasets.get_data_home` (default
        ``$PYSINDY_MME_DATA`` or ``~/pysindy_mme_data``).
    download_if_missing : bool
        Download when no local copy exists; if False, raise ``OSError``.
    remove_offset : bool
        Subtract the record means of u and y (the benchmark README's
        preprocessing).

    Returns
    -------
    SilverboxData (a :class:`sklearn.utils.Bunch`)
        ``u``, ``y``, ``t`` (131,072 samples), ``fs``, ``dt``, ``splits``
        (name -> slice), ``n_init`` (name -> int), ``offset_removed``,
        ``offsets`` (``{"u": .., "y": ..}``, volts subtracted), ``baselines_mv``,
        ``baseline_sources`` (row -> where it was published), ``citation``,
        ``DESCR``, ``filename``, ``sha256``, ``url``, ``page``; methods
        ``split(name)`` and ``rmse_mv(name, y_sim)``.

    Raises
    ------
    OSError
        A local copy whose SHA-256 differs (both hashes and the file are
        named; nothing is written), no copy and ``download_if_missing`` is
        False, or a download that fails or does not verify (nothing is
        written).
    """
    if not isinstance(download_if_missing, bool):
        raise TypeError(
            f"download_if_missing must be a bool, got {download_if_missing!r}"
        )
    if not isinstance(remove_offset, bool):
        raise TypeError(f"remove_offset must be a bool, got {remove_offset!r}")
    home = get_data_home(data_home)
    candidates = [home / SILVERBOX_CSV, home / "silverbox" / SILVERBOX_CSV]
    found = next((p for p in candidates if p.is_file()), None)
    help_text = (
        f"Download SilverboxFiles.zip by hand from {SILVERBOX_PAGE} and put "
        f"{SILVERBOX_CSV} in {home / 'silverbox'}."
    )
    if found is not None:
        raw = found.read_bytes()
        actual = sha256_hex(raw)
        if actual != SILVERBOX_CSV_SHA256:
            raise OSError(
                f"{found} has SHA-256 {actual}, expected {SILVERBOX_CSV_SHA256}: "
                "the file is corrupted or not the official record. Remove it to "
                f"download it again. {help_text}"
            )
    elif not download_if_missing:
        raise OSError(
            f"{SILVERBOX_CSV} not found in {home} or {home / 'silverbox'} and "
            f"download_if_missing is False. {help_text}"
        )
    else:
        found = candidates[1]
        raw = fetch_zip_member(
            SILVERBOX_URL,
            SILVERBOX_CSV,
            SILVERBOX_CSV_SHA256,
            found,
            help_text=help_text,
        )
    return _bunch(_parse_csv(raw, found), found, remove_offset)


def _parse_csv(raw: bytes, path: Path) -> np.ndarray:
    """The (n, 2) array of V1, V2 from the CSV's bytes (header checked)."""
    text = raw.decode("ascii")
    header = text.split("\n", 1)[0].strip().replace('"', "").split(",")
    if header[:2] != ["V1", "V2"]:
        raise OSError(f"{path}: expected a header V1,V2, got {header}")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an empty file is an error, not a warning
        data = np.loadtxt(
            io.StringIO(text), delimiter=",", skiprows=1, usecols=(0, 1), ndmin=2
        )
    if data.shape[0] == 0 or not np.all(np.isfinite(data)):
        raise OSError(f"{path}: no rows, or values that are not finite")
    return data


def _bunch(data, path, remove_offset):
    u, y = data[:, 0].copy(), data[:, 1].copy()
    offsets = {"u": 0.0, "y": 0.0}
    if remove_offset:
        offsets = {"u": float(u.mean()), "y": float(y.mean())}
        u -= offsets["u"]
        y -= offsets["y"]
    return SilverboxData(
        u=u,
        y=y,
        t=np.arange(u.size) / SILVERBOX_FS,
        fs=SILVERBOX_FS,
        dt=1.0 / SILVERBOX_FS,
        splits={name: slice(a, b) for name, (a, b) in SPLITS.items()},
        n_init=dict(N_INIT),
        offset_removed=remove_offset,
        offsets=offsets,
        baselines_mv={k: dict(v) for k, v in BASELINES_MV.items()},
        baseline_sources=dict(BASELINE_SOURCES),
        citation=CITATION,
        DESCR=DESCR,
        filename=str(path),
        sha256=SILVERBOX_CSV_SHA256,
        url=SILVERBOX_URL,
        page=SILVERBOX_PAGE,
    )
