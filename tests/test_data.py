"""The data layer: registry, verification of staged files, and the download path (local HTTP only)."""

import functools
import gzip
import hashlib
import http.server
import shutil
import threading

import pytest

from repro import data
from repro.errors import DataError
from tests.conftest import REPO


def test_registry_covers_every_dataset_with_hashes_and_urls():
    reg = data.registry()
    assert {f.dataset for f in reg.values()} == set(data.DATASETS)
    assert all(len(f.sha256) == 64 for f in reg.values())
    assert len(data.files("ict")) == 61  # neutral + 57 shapes + LICENSE, mtl, vertex_indices.json
    assert all(f.url.startswith("https://") for f in data.files("ict") + data.files("cmu-asfamc") + data.files("bandai"))
    assert not any(f.url for f in data.files("cmu-bvh"))  # converted: no public original
    with pytest.raises(DataError, match="unknown dataset"):
        data.files("nope")


@pytest.mark.data("ict", "cmu-bvh", "cmu-asfamc", "bandai")
def test_staged_data_verifies():
    for name in data.DATASETS:
        s = data.status(name)
        assert s["verified"] == s["files"] and not s["problems"], s


@pytest.fixture
def private_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("REPRO_DATA_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_missing_file_offline_says_how_to_get_it(private_dir):
    with pytest.raises(DataError, match="repro data fetch ict"):
        data.fetch("faces/ict/LICENSE")
    assert "REPRO_DATA_DIR" in data.missing_reason("ict")
    with pytest.raises(DataError, match="no public original"):
        data.fetch("mocap/cmu/135_04.bvh", download=True)


def test_gz_or_plain_both_verified_and_corruption_reported_not_overwritten(private_dir):
    entry = data.registry()["faces/ict/LICENSE"]
    target = private_dir / entry.path
    target.parent.mkdir(parents=True)
    payload = b"not the licence"
    with gzip.open(str(target) + ".gz", "wb") as fh:
        fh.write(payload)
    with pytest.raises(DataError, match="fails its sha256 check"):
        data.fetch(entry.path)
    assert gzip.open(str(target) + ".gz").read() == payload  # untouched
    assert data.status("ict")["problems"]


@pytest.mark.data("ict")
def test_staged_gz_content_matches_upstream_hash(private_dir, monkeypatch):
    monkeypatch.setenv("REPRO_DATA_DIR", str(REPO.parent / "shared" / "data"))
    p = data.fetch("faces/ict/browDown_L.obj")
    assert p.name == "browDown_L.obj.gz"
    with data.open_file("faces/ict/browDown_L.obj") as fh:
        assert hashlib.sha256(fh.read()).hexdigest() == data.registry()["faces/ict/browDown_L.obj"].sha256


@pytest.fixture
def http_server(tmp_path):
    """A local http.server on 127.0.0.1 serving tmp_path/www."""
    www = tmp_path / "www"
    www.mkdir()
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(www))
    http.server.SimpleHTTPRequestHandler.log_message = lambda *a, **k: None
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield www, f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def _serve_licence(www):
    """Copy a small staged file (the ICT LICENSE) into the server folder, or make one when absent."""
    staged = REPO.parent / "shared" / "data" / "faces" / "ict" / "LICENSE"
    body = staged.read_bytes() if staged.exists() else b"MIT License\n" * 20
    (www / "LICENSE").write_bytes(body)
    return body


def test_download_right_hash_accepted(private_dir, http_server):
    www, url = http_server
    body = _serve_licence(www)
    entry = data.DataFile("ict", "faces/ict/LICENSE", hashlib.sha256(body).hexdigest(), f"{url}/LICENSE")
    got = data._download(entry, entry.url, private_dir)
    assert got == private_dir / "faces/ict/LICENSE" and got.read_bytes() == body
    assert sorted(p.name for p in got.parent.iterdir()) == ["LICENSE"]  # nothing half-written beside it


def test_download_wrong_hash_rejected_and_nothing_left(private_dir, http_server):
    www, url = http_server
    _serve_licence(www)
    entry = data.DataFile("ict", "faces/ict/LICENSE", "0" * 64, f"{url}/LICENSE")
    with pytest.raises(DataError, match="rejected"):
        data._download(entry, entry.url, private_dir)
    folder = private_dir / "faces/ict"
    assert not folder.exists() or not any(folder.iterdir()), list(folder.iterdir())


def test_download_http_error_is_a_data_error(private_dir, http_server):
    _, url = http_server
    entry = data.DataFile("ict", "faces/ict/LICENSE", "0" * 64, f"{url}/missing")
    with pytest.raises(DataError, match="failed"):
        data._download(entry, entry.url, private_dir)


def test_fetch_downloads_through_the_registry_when_online(private_dir, http_server, monkeypatch):
    """fetch() itself: absent file + downloads on -> pooch fetch from the registry URL, verified."""
    www, url = http_server
    body = _serve_licence(www)
    entry = data.DataFile("ict", "faces/ict/LICENSE", hashlib.sha256(body).hexdigest(), f"{url}/LICENSE")
    monkeypatch.setitem(data.registry(), entry.path, entry)
    monkeypatch.delenv("REPRO_OFFLINE")
    assert data.fetch(entry.path).read_bytes() == body
    shutil.rmtree(private_dir)
    monkeypatch.setenv("REPRO_OFFLINE", "1")
    with pytest.raises(DataError, match="downloads are off"):
        data.fetch(entry.path)
