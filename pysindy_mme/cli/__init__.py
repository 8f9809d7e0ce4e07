"""Command line: ``pysindy-mme demo`` and ``pysindy-mme discover``.

``parser.py`` holds every option with its default and an example;
``loading.py`` reads the CSV and the user's Python files; ``arguments.py``
turns the options into the arguments of :func:`~pysindy_mme.discover`;
``checks.py`` catches the slips only the command line can name;
``commands.py`` runs the study and prints warnings as plain lines;
``outputs.py`` writes the report, JSON, time series CSV and figures.
"""

from .loading import UsageError, load_csv, load_model
from .main import main
from .parser import build_parser

__all__ = ["main", "build_parser", "load_csv", "load_model", "UsageError"]
