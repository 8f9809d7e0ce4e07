"""The study at the length of real measurements (issues 9 and 20).

The paper's Van der Pol case (x1 measured, noise variance 0.01, ignorance
model, ``PolynomialLibrary(3)``) at 40 Hz over 10, 100, 1,000 and 10,000 s
(401 to 400,001 samples; and 2,500 s: 100,001 samples), and over 10 s at
40 Hz to 40 kHz; with ``--large`` also 10^6 samples, over 25,000 s at 40 Hz
and over 10 s at 100 kHz (issue 20). For every record length: the whole
``discover`` time and, on the same data in the same run, MME alone; exact
terms (seeds: 20 up to 4,001 samples, 5 beyond, 1 at 10^6 samples: a study
there takes minutes); the median largest coefficient error over the exact
seeds; at 10^6 samples the times and the study / MME ratio are medians of
:data:`LARGE_PAIRS` interleaved pairs; peak memory: ``tracemalloc``
(numpy allocations of one study) and
the peak resident set of the row's process (``ru_maxrss``), per sample.

Every row runs in a process of its own, so that one row's peak resident set
is not an earlier row's (the interpreter keeps the pages it once had). The
records are simulated by the parent process and read by the row's from
``.npy`` files, as a user's measurements would be: simulating 10^6 samples
of the truth (``solve_ivp`` and the true correction) peaks at 545 MiB and
leaves about 120 MiB of freed heap in the process that did it, which is the
simulator's, not the study's. The table also gives the resident set before
the study (interpreter, numpy/scipy/scikit-learn/pysindy, the record): about
170 MiB of it is the libraries, whatever the record's length.

Run: ``python benchmarks/bench_long_records.py`` (about 15 minutes on 2
cores; ``--quick`` for the first three rows only; ``--large`` adds the two
10^6-sample rows, about 15 minutes more; ``--only N ...`` runs the rows of
those sample counts). Prints a markdown table, at 10^6 samples the study's stages
(from its own log: input checks, assumed fit, MME, proposals, confirmation, gain,
report), and the targets of issues 9 and 20.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
import warnings
from pathlib import Path

import numpy as np
import pysindy as ps

from pysindy_mme import MME, StudyOptions, discover
from pysindy_mme.systems import van_der_pol

TRUE = {"x1": -1.0, "x2": 1.0, "x1^2 x2": -1.0}
CASES = [  # (seconds, Hz)
    (10, 40),
    (100, 40),
    (10, 400),
    (1_000, 40),
    (10, 4_000),
    (2_500, 40),
    (10_000, 40),
    (10, 40_000),
]
#: issue 20: 10^6 samples, over many periods and at a high rate
#: (and 10 s at 10 kHz: the 10^5 samples the 100 kHz row's growth is from)
LARGE = [(10, 10_000), (25_000, 40), (10, 100_000)]


def study(y, t, system):
    return discover(
        y,
        t,
        assumed_model=system.assumed_model,
        n_states=2,
        measured=[0],
        noise_variance=0.01,
        error_states=[1],
        feature_library=ps.PolynomialLibrary(degree=3),
        options=StudyOptions(feature_names=["x1", "x2"]),
    )


def mme_alone(y, t, system):
    return MME(
        system.assumed_model, 2, measured=[0], noise_variance=0.01, error_states=[1]
    ).fit(y, t)


def timed(fn):
    """``(result, wall seconds, CPU seconds of this process)``."""
    start, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - start, time.process_time() - cpu


#: the study's stages as its log names them (``pysindy_mme`` logger, INFO):
#: each stage's time runs from the message before to its own
STAGES = [
    ("checked:", "input checks"),
    ("1. assumed model", "assumed fit"),
    ("2. MME", "MME"),
    ("3. regression", "proposals"),
    ("4. confirmed", "confirmation"),
    ("5. gain measured", "gain"),
]


class StageClock(logging.Handler):
    """Wall times of a study's stages, from the package's own stage log.

    Attached to the ``pysindy_mme`` logger for one study: the INFO messages
    of :func:`~pysindy_mme.discover` mark the end of each stage (see
    :data:`STAGES`); what follows the last one (the memory test, the
    conclusion) is "report". Costs nothing measurable: six messages.
    """

    def __init__(self):
        super().__init__(level=logging.INFO)
        self.marks = []

    def emit(self, record):
        if record.levelno == logging.INFO:
            self.marks.append((time.perf_counter(), record.getMessage()))

    def timed_study(self, fn):
        """``timed(fn)`` with the stages of the study it runs recorded."""
        logger = logging.getLogger("pysindy_mme")
        level = logger.level
        logger.addHandler(self)
        logger.setLevel(logging.INFO)
        self.marks = []
        try:
            start = time.perf_counter()
            out = timed(fn)
            end = time.perf_counter()
        finally:
            logger.removeHandler(self)
            logger.setLevel(level)
        return out, self.durations(start, end)

    def durations(self, start, end) -> dict:
        """``{stage: seconds}``; a stage whose message is missing is left out."""
        out, last = {}, start
        for prefix, name in STAGES:
            at = [t for t, msg in self.marks if msg.startswith(prefix)]
            if at:
                out[name] = at[0] - last
                last = at[0]
        out["report"] = end - last
        return out


def write_records(seconds, rate, n_seeds, folder):
    """Seeds ``0 .. n_seeds - 1`` of the row as ``y{seed}.npy`` and
    ``t.npy`` in ``folder`` (the measurements only)."""
    system = van_der_pol()
    t = system.time(seconds, rate)
    np.save(Path(folder) / "t.npy", t)
    for seed in range(n_seeds):
        np.save(Path(folder) / f"y{seed}.npy", system.measure(seed, t=t).y)


def read_record(folder, seed):
    """``(y, t)`` of one seed written by :func:`write_records`."""
    return np.load(Path(folder) / f"y{seed}.npy"), np.load(Path(folder) / "t.npy")


def resident_mib():
    """This process's resident set now (MiB; NaN where /proc is not there)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):
        return float("nan")


#: timed (study, MME alone) pairs per seed at 10^6 samples: one seed runs
#: there, and on this 2-core virtual machine the same study's wall time moved
#: by 10 % between runs (25.4 to 28.1 s, session 21); the row reports the
#: medians of interleaved pairs
LARGE_PAIRS = 3


def run_case(seconds, rate, n_seeds, folder, trace=True, pairs=1):
    """One row, in this process, on the records in ``folder``: times, exact
    terms, peak memory. ``pairs``: timed (study, MME alone) pairs per seed,
    interleaved (the row's times are the medians over all of them).

    One untimed MME fit of seed 0 comes first. On this machine a process's
    first use of memory costs about 2 ms per MB (128 MB written for the
    first time: 257 ms, 0.26 s of system time; the same size allocated again
    after it was freed: 8 ms). At 10^6 samples that was about 3 s of system
    time for the study's 1.4 GB, charged to the study (timed first) while
    MME alone, timed second, reused the pages the study had freed: a cold
    study against a warm MME. After the warm-up both run on the pages MME
    needs; the study still pays for the memory it needs beyond MME's, which
    is its own cost.
    """
    system = van_der_pol()
    exact, errors, t_study, t_mme, c_study, c_mme = 0, [], [], [], [], []
    stages = []
    clock = StageClock()
    before = float("nan")
    for seed in range(n_seeds):
        y, t = read_record(folder, seed)
        if seed == 0:
            before = resident_mib()
            # the untimed warm-up (see the docstring)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                mme_alone(y, t, system)
        for pair in range(pairs):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                (res, sec, cpu), split = clock.timed_study(
                    lambda y=y, t=t: study(y, t, system)
                )
                _, sec_mme, cpu_mme = timed(lambda y=y, t=t: mme_alone(y, t, system))
            t_study.append(sec)
            t_mme.append(sec_mme)
            stages.append(split)
            c_study.append(cpu)
            c_mme.append(cpu_mme)
            if seed == pair == 0:
                # the peak of one study (and MME) in this process: a second
                # study in the same process peaks higher (about 1.7 GB
                # against 1.4 at 10^6 samples: the heap keeps freed fragments)
                rss_first = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024.0
        found = res.terms["x2"]
        if set(found) == set(TRUE):
            exact += 1
            errors.append(max(abs(found[k] - v) for k, v in TRUE.items()))
    # the resident peak before tracemalloc's own bookkeeping inflates it:
    # of the first pair (with several pairs, of all of them as well)
    rss_all = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024.0
    rss = rss_first if pairs > 1 else rss_all
    ratios = np.array(t_study) / np.array(t_mme)
    peak = float("nan")
    if trace:
        y, t = read_record(folder, 0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tracemalloc.start()
            study(y, t, system)
            peak = tracemalloc.get_traced_memory()[1] / 2**20
            tracemalloc.stop()
    return {
        "seconds": seconds,
        "rate": rate,
        "n": t.size,
        "seeds": n_seeds,
        "pairs": pairs,
        "exact": exact,
        "error": float(np.median(errors)) if errors else float("nan"),
        "time": float(np.median(t_study)),
        "mme": float(np.median(t_mme)),
        # CPU time: on a machine shared with other work the wall-clock
        # ratio of two runs moves with the load; the CPU-time ratio less
        "cpu": float(np.median(c_study)),
        "cpu_mme": float(np.median(c_mme)),
        # the median of the pairs' own ratios (each pair ran back to back)
        "ratio": float(np.median(ratios)),
        "ratio_range": [float(np.min(ratios)), float(np.max(ratios))],
        "peak": peak,
        "rss": rss / 2**20,
        "rss_all_pairs": rss_all / 2**20,
        "rss_before": before,
        "rss_per_sample": rss / t.size,
        # the median of each stage over the pairs (seconds)
        "stages": {
            name: float(np.median([st[name] for st in stages if name in st]))
            for name in stages[0]
        },
    }


def run_in_subprocess(seconds, rate, n_seeds, trace, pairs=1):
    """:func:`run_case` in a fresh interpreter (its own peak resident set),
    on records this process simulates and writes first."""
    with tempfile.TemporaryDirectory() as folder:
        write_records(seconds, rate, n_seeds, folder)
        cmd = [sys.executable, __file__, "--row", str(seconds), str(rate)]
        cmd += [str(n_seeds), "--records", folder, "--pairs", str(pairs)]
        if not trace:
            cmd.append("--no-trace")
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="first three rows")
    parser.add_argument(
        "--large", action="store_true", help="add the 10^6-sample rows (issue 20)"
    )
    parser.add_argument(
        "--only", type=int, nargs="+", help="run only rows of these sample counts"
    )
    parser.add_argument("--row", nargs=3, type=float, help=argparse.SUPPRESS)
    parser.add_argument("--no-trace", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--pairs", type=int, default=1, help=argparse.SUPPRESS)
    parser.add_argument(
        "--records",
        help="with --row: the folder of its records (default: simulated "
        "into a temporary folder by a child process first)",
    )
    parser.add_argument("--write", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.write:  # seconds, rate, seeds, folder: the records of one row
        seconds, rate, n_seeds, folder = args.write
        write_records(
            _number(float(seconds)), _number(float(rate)), int(float(n_seeds)), folder
        )
        return
    if args.row:  # one row in this process (see run_in_subprocess)
        seconds, rate = _number(args.row[0]), _number(args.row[1])
        n_seeds = int(args.row[2])
        if args.records is None:
            with tempfile.TemporaryDirectory() as folder:
                # simulated by another process: not this one's heap
                cmd = [sys.executable, __file__, "--write", *map(str, args.row)]
                subprocess.run([*cmd, folder], check=True)
                row = run_case(
                    seconds, rate, n_seeds, folder, not args.no_trace, args.pairs
                )
        else:
            row = run_case(
                seconds, rate, n_seeds, args.records, not args.no_trace, args.pairs
            )
        print(json.dumps(row))
        return
    cases = CASES[:3] if args.quick else CASES + (LARGE if args.large else [])
    if args.only:
        cases = [c for c in CASES + LARGE if int(round(c[0] * c[1])) + 1 in args.only]
    rows = []
    for seconds, rate in cases:
        n = int(round(seconds * rate)) + 1
        seeds = 20 if n <= 4_001 else 5 if n < 1_000_000 else 1
        # tracemalloc doubles a study's time: not at 10^6 samples (the
        # resident peak is the figure there)
        row = run_in_subprocess(
            seconds,
            rate,
            seeds,
            trace=n < 1_000_000,
            pairs=LARGE_PAIRS if n >= 1_000_000 else 1,
        )
        rows.append(row)
        print(
            f"{row['n']:>8} samples: {row['time']:.2f} s/study, MME {row['mme']:.2f} s,"
            f" exact {row['exact']}/{row['seeds']}, peak RSS {row['rss']:.0f} MiB",
            flush=True,
        )
    print(
        "\n| record | samples | exact terms | median largest coef. error | s / study "
        "| MME alone (s) | study / MME | study / MME (CPU) | peak MB (tracemalloc) "
        "| peak RSS MB | RSS kB / sample | RSS before the study MB |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['seconds']:,} s at {r['rate']:,} Hz | {r['n']:,} | "
            f"{r['exact']}/{r['seeds']} | {r['error']:.4f} | {r['time']:.2f} | "
            f"{r['mme']:.2f} | {r['ratio']:.2f} | "
            f"{r['cpu'] / r['cpu_mme']:.1f} | {r['peak']:.0f} | "
            f"{r['rss']:.0f} | {r['rss_per_sample'] / 1024:.2f} | "
            f"{r['rss_before']:.0f} |"
        )
    by_n = {r["n"]: r for r in rows}
    print("\nTargets (issue 9):")
    print(f"- exact terms in every seed: {all(r['exact'] == r['seeds'] for r in rows)}")
    if 40_001 in by_n:
        print(
            "- coefficient error at 40,001 samples (<= 0.01): "
            f"{by_n[40_001]['error']:.4f}"
        )
    growth = [
        (a["n"], b["n"], b["time"] / a["time"])
        for a in rows
        for b in rows
        if a["rate"] == b["rate"] == 40
        and b["n"] == 10 * a["n"] - 9
        and a["n"] >= 4_001
    ]
    for a, b, g in growth:
        print(f"- time growth {a:,} -> {b:,} samples: x{g:.1f} (target <= 12)")
    if 100_001 in by_n:
        r = by_n[100_001]
        print(
            f"- 100,001 samples: {r['time']:.1f} s (<= 15), "
            f"{r['time'] / r['mme']:.1f}x MME (<= 15)"
        )

    big = [r for r in rows if r["n"] >= 1_000_000]
    if big:
        # where the study's time goes, against MME alone (issue 20: the study
        # at most 3x MME alone)
        names = list(big[0]["stages"])
        print("\nStages of the study (s, median over the pairs; from its log):\n")
        print("| record | " + " | ".join(names) + " | study | MME alone |")
        print("|---|" + "---:|" * (len(names) + 2))
        for r in big:
            cells = " | ".join(f"{r['stages'].get(k, float('nan')):.2f}" for k in names)
            print(
                f"| {r['seconds']:,} s at {r['rate']:,} Hz | {cells} | "
                f"{r['time']:.2f} | {r['mme']:.2f} |"
            )
        print("\nTargets (issue 20):")
    for r in big:
        # the row of 10^5 samples at the same rate or over the same time
        ten = [
            a
            for a in rows
            if a["n"] == (r["n"] - 1) // 10 + 1
            and (a["rate"] == r["rate"] or a["seconds"] == r["seconds"])
        ]
        growth = (
            f", growth from {ten[0]['n']:,}: x{r['time'] / ten[0]['time']:.1f} (<= 11)"
            if ten
            else ""
        )
        low, high = r.get("ratio_range", [r["time"] / r["mme"]] * 2)
        print(
            f"- {r['seconds']:,} s at {r['rate']:,} Hz: {r['ratio']:.2f}x MME (<= 3; "
            f"median of {r['pairs']} interleaved pairs, {low:.2f}-{high:.2f}; CPU "
            f"time {r['cpu'] / r['cpu_mme']:.2f}x){growth}, "
            f"peak RSS {r['rss_per_sample'] / 1024:.2f} kB per sample (<= 1.5), "
            f"exact {r['exact']}/{r['seeds']}"
        )


def _number(value: float):
    """A whole number of seconds or hertz as an int (the labels of the table)."""
    return int(value) if float(value).is_integer() else value


if __name__ == "__main__":
    main()
