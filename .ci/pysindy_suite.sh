#!/usr/bin/env bash
# Conformance: pysindy's own test suite, from the sdist of the pysindy version
# installed here, with FloatingFStepwise as SINDy's default optimizer and added
# to every optimizer parametrisation (tests/conformance/pysindy_plugin.py).
# Expected failures, each with its reason, are listed in one place:
# tests/conformance/pysindy_expected.py (a listed test that passes, or an
# entry that matches no test, fails the run).
#
# Run it in the environment to test (CI: .ci/run's .venv, after the main tests):
#   bash .ci/pysindy_suite.sh [extra pytest arguments]
# It installs what pysindy's tests import (its cvxpy and sbr extras, and
# pytest-lazy-fixtures in place of pytest-lazy-fixture, which does not run on
# pytest 8+), not gurobipy (see the plugin). Measured: about 15 s of installs
# and downloads, 35-50 s of tests.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
version=$(python -c "import pysindy; print(pysindy.__version__)")
echo "pysindy suite: pysindy $version with FloatingFStepwise"
pip install --quiet "pysindy[cvxpy,sbr]==$version" pytest-lazy-fixtures
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
pip download --quiet --no-deps --no-binary pysindy "pysindy==$version" -d "$work"
tar -xzf "$work/pysindy-$version.tar.gz" -C "$work"
src="$work/pysindy-$version"
# The installed pysindy is the one under test, not the sdist's source tree.
rm -rf "$src/pysindy"
cd "$src"
# pysindy's own pytest configuration (its pyproject.toml) applies: slow and
# notebook tests deselected; the notebooks' module needs jupyter, not run.
PYTHONPATH="$root/tests/conformance${PYTHONPATH:+:$PYTHONPATH}" \
    python -m pytest test -p pysindy_plugin -p no:cacheprovider \
    --ignore=test/test_notebooks.py -q -rfE "$@"
