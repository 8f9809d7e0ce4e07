"""The defaults the documentation quotes are the defaults in the code.

Each claim is a pattern in a document, the callable whose signature holds the
default, and the parameter: the number in the text is read back and compared
with ``inspect.signature`` (so a changed default fails here until the docs
follow).
"""

import inspect
import re
from pathlib import Path

import pytest

from pysindy_mme import FloatingFStepwise, StudyOptions

ROOT = Path(__file__).resolve().parents[1]

CLAIMS = [
    # (file, regex with one group: the quoted default, callable, parameter)
    (
        "docs/errors.md",
        r"`alpha must lie strictly between 0 and 1` \| significance level \| "
        r"e\.g\. ([0-9.e-]+) \(default\)",
        StudyOptions,
        "alpha",
    ),
    (
        "docs/errors.md",
        r"keep the default `([0-9.e-]+)` unless you know why",
        FloatingFStepwise,
        "tolerance",
    ),
    (
        "docs/errors.md",
        r"`refit must be True or False` \(TypeError\) \| not a bool \| `(True|False)` "
        r"\(default\)",
        StudyOptions,
        "refit",
    ),
]


@pytest.mark.parametrize(
    "path, pattern, func, name", CLAIMS, ids=[f"{c[0]}:{c[3]}" for c in CLAIMS]
)
def test_quoted_default_is_the_code_default(path, pattern, func, name):
    text = (ROOT / path).read_text()
    match = re.search(pattern, text)
    assert match, f"{path} no longer quotes the default of {name}"
    default = inspect.signature(func).parameters[name].default
    quoted = match.group(1)
    if isinstance(default, bool):
        assert quoted == str(default)
    else:
        assert float(quoted) == float(default), (name, quoted, default)


def test_readme_quotes_discover_alpha_as_the_code_does():
    default = inspect.signature(StudyOptions).parameters["alpha"].default
    for path in ("README.md", "docs/errors.md"):
        for match in re.finditer(
            r"alpha\s*=\s*([0-9.]+)[^0-9]", (ROOT / path).read_text()
        ):
            value = float(match.group(1))
            # every 'alpha = x' quoted as discover's default must be it
            line = (ROOT / path).read_text()[match.start() : match.start() + 80]
            if "default" in line:
                assert value == default, (path, line)
