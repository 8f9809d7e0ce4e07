"""fetch_silverbox: the shared local copy (offline) and a loopback download.

No test needs the internet: the download path is served by an HTTP server on
127.0.0.1 from a zip built in tmp_path around a small fake CSV, with the
module's URL and checksum constants pointed at it.
"""

from __future__ import annotations

import csv
import hashlib
import http.server
import io
import threading
import urllib.request
import zipfile
from pathlib import Path

import numpy as np
import pytest

from pysindy_mme.datasets import fetch_silverbox, get_data_home
from pysindy_mme.datasets import silverbox as sb

SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "silverbox"
needs_shared = pytest.mark.skipif(
    not (SHARED / "SNLS80mV.csv").is_file(),
    reason=f"the Silverbox record is not at {SHARED} (see its README.md there)",
)


def _no_network(*args, **kwargs):
    raise AssertionError("the network was used")


def _read_with_csv_module(path):
    """Independent reader: the standard library's csv module."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0][:2] == ["V1", "V2"]
    return np.array([[float(r[0]), float(r[1])] for r in rows[1:] if r])


@pytest.fixture(scope="module")
def shared_raw():
    if not (SHARED / "SNLS80mV.csv").is_file():
        pytest.skip(f"the Silverbox record is not at {SHARED}")
    return _read_with_csv_module(SHARED / "SNLS80mV.csv")


# --- the shared copy, offline ---------------------------------------------------


@needs_shared
def test_shared_copy_shapes_fs_splits_means(monkeypatch, shared_raw):
    monkeypatch.setattr(urllib.request, "urlopen", _no_network)
    d = fetch_silverbox(SHARED)
    assert isinstance(d, sb.Bunch)
    assert d.u.shape == d.y.shape == d.t.shape == (131072,)
    assert d.fs == 610.35 and d.dt == pytest.approx(1 / 610.35)
    np.testing.assert_allclose(np.diff(d.t), 1 / 610.35, rtol=1e-9)
    assert d.t[0] == 0.0
    lengths = {k: s.stop - s.start for k, s in d.splits.items()}
    assert lengths == {
        "estimation": 86750,
        "train": 65062,
        "test_multisine": 21688,
        "test_arrow_full": 40475,
        "test_arrow_no_extrapolation": 32000,
    }
    est = d.splits["estimation"]
    assert d.splits["train"].stop == est.start + int(0.75 * (est.stop - est.start))
    assert d.splits["test_multisine"] == slice(d.splits["train"].stop, est.stop)
    assert d.n_init["test_arrow_full"] == 50 and d.n_init["train"] == 0
    # offsets: the record means, removed
    assert d.offset_removed
    assert d.offsets["u"] == pytest.approx(shared_raw[:, 0].mean(), rel=1e-12)
    assert d.offsets["y"] == pytest.approx(shared_raw[:, 1].mean(), rel=1e-12)
    assert abs(d.u.mean()) < 1e-15 and abs(d.y.mean()) < 1e-15
    np.testing.assert_allclose(d.y + d.offsets["y"], shared_raw[:, 1], atol=1e-15)
    assert (
        d.sha256 == hashlib.sha256((SHARED / "SNLS80mV.csv").read_bytes()).hexdigest()
    )
    assert "Wigren" in d.citation and "Wigren" in d.DESCR
    assert d.baselines_mv["polynomial NARX (forward regression, tuned per split)"][
        "test_arrow_full"
    ] == (4.15, 4.15)


@needs_shared
def test_raw_values_without_offset_removal(shared_raw):
    d = fetch_silverbox(SHARED, download_if_missing=False, remove_offset=False)
    assert not d.offset_removed and d.offsets == {"u": 0.0, "y": 0.0}
    np.testing.assert_array_equal(np.column_stack([d.u, d.y]), shared_raw)


@needs_shared
def test_split_and_score(shared_raw):
    d = fetch_silverbox(SHARED, download_if_missing=False)
    s = d.split("test_arrow_no_extrapolation")
    assert (s.start, s.stop, s.n_init, s.name) == (
        100,
        32100,
        50,
        "test_arrow_no_extrapolation",
    )
    np.testing.assert_array_equal(s.y, d.y[100:32100])
    s.y[:] = 0.0  # a copy: the record is unchanged
    assert np.any(d.y[100:32100] != 0.0)
    y = d.split("test_multisine").y
    assert d.rmse_mv("test_multisine", y) == 0.0
    off = y + 0.002
    off[:50] = 1.0  # the settling samples are not scored
    assert d.rmse_mv("test_multisine", off) == pytest.approx(2.0, rel=1e-9)
    with pytest.raises(ValueError, match="y_sim has 10 samples but split"):
        d.rmse_mv("test_multisine", np.zeros(10))
    with pytest.raises(ValueError, match="split must be one of"):
        d.split("validation")


@needs_shared
def test_folder_layouts_and_environment_variable(tmp_path, monkeypatch):
    monkeypatch.setattr(urllib.request, "urlopen", _no_network)
    (tmp_path / "silverbox").mkdir()
    (tmp_path / "silverbox" / "SNLS80mV.csv").symlink_to(SHARED / "SNLS80mV.csv")
    a = fetch_silverbox(tmp_path)  # data_home/silverbox/SNLS80mV.csv
    monkeypatch.setenv("PYSINDY_MME_DATA", str(SHARED))
    b = fetch_silverbox()  # data_home from the environment, file directly in it
    np.testing.assert_array_equal(a.y, b.y)
    assert b.filename == str(SHARED / "SNLS80mV.csv")


@needs_shared
def test_corrupted_copy_is_refused_and_nothing_written(tmp_path, monkeypatch):
    monkeypatch.setattr(urllib.request, "urlopen", _no_network)
    raw = bytearray((SHARED / "SNLS80mV.csv").read_bytes())
    raw[1000] = ord("7") if raw[1000] != ord("7") else ord("8")
    bad = tmp_path / "SNLS80mV.csv"
    bad.write_bytes(bytes(raw))
    actual = hashlib.sha256(bytes(raw)).hexdigest()
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(OSError) as err:
        fetch_silverbox(tmp_path)
    msg = str(err.value)
    assert str(bad) in msg and actual in msg and sb.SILVERBOX_CSV_SHA256 in msg
    assert sorted(tmp_path.rglob("*")) == before
    assert bad.read_bytes() == bytes(raw)


def test_missing_without_download_is_a_clear_error(tmp_path):
    with pytest.raises(OSError, match="download_if_missing is False"):
        fetch_silverbox(tmp_path / "empty", download_if_missing=False)
    assert not (tmp_path / "empty").exists()


# --- download through a loopback server ---------------------------------------


def _fake_csv(n=300, seed=0):
    rng = np.random.default_rng(seed)
    data = rng.normal(size=(n, 2)) * [0.02, 0.05] + [0.006, 0.001]
    text = [[f"{a:.7g}", f"{b:.7g}"] for a, b in data]
    lines = ['"V1","V2",'] + [f"{a},{b}," for a, b in text]
    return ("\n".join(lines) + "\n\n").encode(), np.array(text, dtype=float)


def _zip(member_bytes, name="SilverboxFiles/SNLS80mV.csv"):
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(name, member_bytes)
        zf.writestr("SilverboxFiles/README.txt", b"fake")
    return buf.getvalue()


class _Server:
    """Serves ``payload`` for every GET on 127.0.0.1; counts the requests."""

    def __init__(self, payload):
        outer = self
        self.payload = payload
        self.hits = 0

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self):
                outer.hits += 1
                self.send_response(200)
                self.send_header("Content-Length", str(len(outer.payload)))
                self.end_headers()
                self.wfile.write(outer.payload)

            def log_message(self, *args):
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/SilverboxFiles.zip"
        self.thread = threading.Thread(
            target=self.httpd.serve_forever, kwargs={"poll_interval": 0.02}, daemon=True
        )
        self.thread.start()

    def stop(self):
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join()


@pytest.fixture
def serve(monkeypatch):
    servers = []

    def start(payload, expected_csv_sha):
        server = _Server(payload)
        servers.append(server)
        monkeypatch.setattr(sb, "SILVERBOX_URL", server.url)
        monkeypatch.setattr(sb, "SILVERBOX_CSV_SHA256", expected_csv_sha)
        return server

    yield start
    for server in servers:
        try:
            server.stop()
        except OSError:
            pass


def test_download_once_then_offline(tmp_path, serve):
    csv_bytes, data = _fake_csv()
    server = serve(_zip(csv_bytes), hashlib.sha256(csv_bytes).hexdigest())
    home = tmp_path / "home"
    d = fetch_silverbox(home)
    assert server.hits == 1
    cached = home / "silverbox" / "SNLS80mV.csv"
    assert cached.read_bytes() == csv_bytes
    assert sorted(p.name for p in home.rglob("*")) == ["SNLS80mV.csv", "silverbox"]
    np.testing.assert_allclose(d.u + d.offsets["u"], data[:, 0], rtol=1e-12)
    np.testing.assert_allclose(d.y + d.offsets["y"], data[:, 1], rtol=1e-12)
    server.stop()
    again = fetch_silverbox(home)  # the server is gone: read from the cache
    assert server.hits == 1
    np.testing.assert_array_equal(again.y, d.y)
    # the published results travel with the record, each with its source
    assert d.baselines_mv == sb.BASELINES_MV
    assert d.baseline_sources == sb.BASELINE_SOURCES


def test_published_results_have_the_best_arrow_rows_and_a_source_each():
    best = {
        "polynomial nonlinear state space, PNLSS (Paduart et al. 2010)": 0.26,
        "nonlinear ARX (Silverbox benchmark results)": 0.30,
    }
    for name, arrow_full in best.items():
        assert sb.BASELINES_MV[name]["test_arrow_full"] == (arrow_full, arrow_full)
    assert "Automatica 46(4)" in sb.BASELINE_SOURCES[next(iter(best))]
    # no published row on the arrow is better than these two
    lows = [
        v["test_arrow_full"][0]
        for v in sb.BASELINES_MV.values()
        if v and v.get("test_arrow_full")
    ]
    assert min(lows) == 0.26
    assert set(sb.BASELINE_SOURCES) == set(sb.BASELINES_MV)
    splits = {"test_arrow_full", "test_arrow_no_extrapolation", "test_multisine"}
    for name, values in sb.BASELINES_MV.items():
        assert set(values) == splits, name
        for v in values.values():
            assert v is None or 0 < v[0] <= v[1], (name, v)
    assert "0.26 mV" in sb.DESCR and "baseline_sources" in sb.DESCR


@pytest.mark.parametrize(
    "payload, match",
    [
        (_zip(b'"V1","V2",\n9,9,\n'), "has SHA-256"),
        (b"<!DOCTYPE html><html>virus scan warning</html>", "is not a zip archive"),
        (_zip(b"x", name="SilverboxFiles/other.csv"), "holds no SNLS80mV.csv"),
    ],
    ids=["bad-bytes", "not-a-zip", "member-missing"],
)
def test_bad_download_is_an_error_and_writes_nothing(tmp_path, serve, payload, match):
    csv_bytes, _ = _fake_csv()
    serve(payload, hashlib.sha256(csv_bytes).hexdigest())
    home = tmp_path / "home"
    with pytest.raises(OSError, match=match) as err:
        fetch_silverbox(home)
    assert "127.0.0.1" in str(err.value)
    assert not home.exists()


def test_checksum_mismatch_names_both_hashes(tmp_path, serve):
    csv_bytes, _ = _fake_csv()
    other, _ = _fake_csv(seed=1)
    expected = hashlib.sha256(csv_bytes).hexdigest()
    serve(_zip(other), expected)
    with pytest.raises(OSError) as err:
        fetch_silverbox(tmp_path)
    assert expected in str(err.value)
    assert hashlib.sha256(other).hexdigest() in str(err.value)
    assert list(tmp_path.iterdir()) == []


def test_unreachable_server(tmp_path, serve):
    csv_bytes, _ = _fake_csv()
    server = serve(_zip(csv_bytes), hashlib.sha256(csv_bytes).hexdigest())
    server.stop()
    with pytest.raises(OSError, match="could not download http://127.0.0.1"):
        fetch_silverbox(tmp_path / "home")
    assert not (tmp_path / "home").exists()


# --- arguments -----------------------------------------------------------------------


def test_data_home_resolution(tmp_path, monkeypatch):
    monkeypatch.delenv("PYSINDY_MME_DATA", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert get_data_home() == tmp_path / "pysindy_mme_data"
    monkeypatch.setenv("PYSINDY_MME_DATA", "~/elsewhere")
    assert get_data_home() == tmp_path / "elsewhere"
    assert get_data_home(tmp_path / "x") == tmp_path / "x"
    assert not (tmp_path / "pysindy_mme_data").exists()  # never created by a lookup
    (tmp_path / "f").write_text("")
    with pytest.raises(ValueError, match="data_home must be a folder"):
        get_data_home(tmp_path / "f")
    with pytest.raises(TypeError, match="data_home must be a folder path"):
        get_data_home(3)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"download_if_missing": "yes"}, "download_if_missing"),
        ({"remove_offset": 1}, "remove_offset"),
    ],
)
def test_bad_flags(tmp_path, kwargs, match):
    with pytest.raises(TypeError, match=match):
        fetch_silverbox(tmp_path, **kwargs)
