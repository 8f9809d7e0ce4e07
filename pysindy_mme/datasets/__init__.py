"""Public measurement records, fetched like scikit-learn's ``fetch_*`` functions.

Each ``fetch_*`` reads a verified local copy when there is one (no network),
else downloads the official archive once into the data home and keeps only
the checksum-verified file it needs.
"""

from ._base import get_data_home
from .silverbox import fetch_silverbox

__all__ = ["fetch_silverbox", "get_data_home"]
