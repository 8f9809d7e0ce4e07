"""``pysindy-mme``: the entry point.

Bad input ends with one line on standard error, ``pysindy-mme: error:
<message>``, naming the option (or the ``file:line`` of the user's model
file) and what to do, and exit code 2, before anything is written.
"""

from __future__ import annotations

import sys

from .commands import run_demo, run_discover
from .loading import UsageError, forget_modules
from .parser import build_parser

__all__ = ["main"]


def main(argv=None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    forget_modules()
    try:
        if args.command == "demo":
            return run_demo(args)
        return run_discover(args)
    except UsageError as exc:
        print(f"pysindy-mme: error: {exc}", file=sys.stderr)
        return 2
    finally:
        forget_modules()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
