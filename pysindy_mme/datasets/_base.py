"""Data home, checksums and a download that never leaves a partial file.

Nothing is written to the data home unless it has been verified: a download
is held in memory, the wanted member is taken out of the archive, its SHA-256
compared with the known one, and only then written to a temporary file in the
target folder and renamed into place (atomic on one file system).
"""

from __future__ import annotations

import hashlib
import io
import os
import tempfile
import urllib.error
import urllib.request
import zipfile
from pathlib import Path

__all__ = ["get_data_home", "sha256_hex", "fetch_zip_member"]

ENV_VAR = "PYSINDY_MME_DATA"
_MAX_DOWNLOAD = 64 * 2**20  # bytes; the archives fetched here are a few MB


def get_data_home(data_home=None) -> Path:
    """The folder where data sets are looked for and cached.

    ``data_home`` if given, else the environment variable
    ``PYSINDY_MME_DATA``, else ``~/pysindy_mme_data``. ``~`` is expanded. The
    folder is not created here (only a download creates it).

    Raises
    ------
    TypeError
        ``data_home`` is not a string, a path or None.
    ValueError
        ``data_home`` names an existing file.
    """
    if data_home is None:
        data_home = os.environ.get(ENV_VAR) or Path("~") / "pysindy_mme_data"
    if not isinstance(data_home, (str, os.PathLike)):
        raise TypeError(f"data_home must be a folder path or None, got {data_home!r}")
    path = Path(data_home).expanduser()
    if path.is_file():
        raise ValueError(f"data_home must be a folder, but {path} is a file")
    return path


def sha256_hex(data: bytes) -> str:
    """SHA-256 of ``data`` as 64 lowercase hex digits."""
    return hashlib.sha256(data).hexdigest()


def fetch_zip_member(url, member, sha256, target: Path, *, help_text="", timeout=60):
    """Download the zip at ``url``, verify ``member``, write it to ``target``.

    ``member`` is matched by file name anywhere in the archive. Returns the
    member's bytes. Raises ``OSError`` naming the URL (and ``help_text``: how
    to get the file by hand) when the download fails, the answer is not a
    zip archive, the member is missing or its SHA-256 differs from
    ``sha256`` (both hashes in the message). On any error nothing is left in
    ``target``'s folder (a folder created here is removed again).
    """
    archive = _download(url, timeout, help_text)
    try:
        with zipfile.ZipFile(io.BytesIO(archive)) as zf:
            names = [n for n in zf.namelist() if Path(n).name == member]
            if not names:
                raise OSError(
                    f"the archive downloaded from {url} holds no {member} "
                    f"(it holds {zf.namelist()[:10]}). {help_text}"
                )
            data = zf.read(names[0])
    except zipfile.BadZipFile:
        raise OSError(
            f"the file downloaded from {url} ({len(archive)} bytes, starting "
            f"{archive[:40]!r}) is not a zip archive. {help_text}"
        ) from None
    actual = sha256_hex(data)
    if actual != sha256:
        raise OSError(
            f"{member} in the archive downloaded from {url} has SHA-256 {actual}, "
            f"expected {sha256}; nothing was written to {target.parent}. {help_text}"
        )
    write_atomically(target, data)
    return data


def write_atomically(target: Path, data: bytes) -> None:
    """Write ``data`` to ``target`` through a temporary file and a rename."""
    folder = target.parent
    created = [p for p in (folder, *folder.parents) if not p.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{target.name}.", suffix=".part")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        for path in created:  # innermost first
            try:
                path.rmdir()
            except OSError:
                break
        raise


def _download(url, timeout, help_text) -> bytes:
    """The body of ``url`` (at most _MAX_DOWNLOAD bytes), held in memory."""
    try:
        with urllib.request.urlopen(url, timeout=timeout) as response:
            data = response.read(_MAX_DOWNLOAD + 1)
    except (urllib.error.URLError, OSError, ValueError) as exc:
        raise OSError(f"could not download {url}: {exc}. {help_text}") from exc
    if len(data) > _MAX_DOWNLOAD:
        raise OSError(
            f"the download from {url} exceeds {_MAX_DOWNLOAD} bytes; stopped. "
            f"{help_text}"
        )
    return data
