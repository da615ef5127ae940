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


# ------------------------------------------------------------------ issue 23: paths stay inside, special files refused
def _finishes(fn, unblock=None, seconds=60):
    """``fn()``'s outcome (value or exception), run in a thread so that a regression (a read that
    blocks on a FIFO or never ends on /dev/zero) fails the test instead of hanging the suite;
    ``unblock`` is called if it did not finish (e.g. opens the FIFO for writing to free the reader)."""
    out = {}

    def run():
        try:
            out["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 (handed to the test)
            out["error"] = exc

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(seconds)
    if t.is_alive():
        if unblock is not None:
            unblock()
        pytest.fail(f"{fn} did not return within {seconds} s: it hangs on a special file")
    if "error" in out:
        raise out["error"]
    return out.get("value")


def _free_fifo(path):
    def unblock():
        import os

        fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
        os.close(fd)
    return unblock


@pytest.mark.parametrize("name", ["../../../../etc/passwd", "../outside.txt", "faces/../../outside.txt",
                                  "/etc/passwd", "faces/ict/\x00LICENSE"])
def test_locate_refuses_a_path_leaving_the_data_folder(private_dir, name):
    private_dir.mkdir()
    (private_dir.parent / "outside.txt").write_text("secret")
    with pytest.raises(DataError, match="outside its folder|absolute path|NUL"):
        data.locate(name)


def test_locate_refuses_a_symlink_leading_outside_and_fetch_never_reads_it(private_dir, tmp_path):
    folder = private_dir / "faces" / "ict"
    folder.mkdir(parents=True)
    (tmp_path / "elsewhere").write_text("not the licence")
    (folder / "LICENSE").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(DataError, match="outside its folder"):
        data.locate("faces/ict/LICENSE")
    with pytest.raises(DataError, match="outside its folder"):
        data.fetch("faces/ict/LICENSE")
    s = data.status("ict")  # `repro data list`: reported as a problem, not raised
    assert s["present"] == 1 and s["verified"] == 0 and "outside its folder" in s["problems"][0]
    (folder / "LICENSE").unlink()
    (folder / "LICENSE.gz").symlink_to(tmp_path / "elsewhere")  # the .gz form: the same rule
    with pytest.raises(DataError, match="outside its folder"):
        data.locate("faces/ict/LICENSE")
    # a symlink that stays inside the folder is followed
    (folder / "LICENSE.gz").unlink()
    (folder / "real").write_text("x")
    (folder / "LICENSE").symlink_to(folder / "real")
    assert data.locate("faces/ict/LICENSE") == (folder / "real").resolve()


def test_locate_refuses_what_is_not_a_regular_file(private_dir):
    import os

    folder = private_dir / "faces" / "ict"
    folder.mkdir(parents=True)
    os.mkfifo(folder / "LICENSE")
    with pytest.raises(DataError, match="FIFO"):
        data.locate("faces/ict/LICENSE")
    with pytest.raises(DataError, match="FIFO"):
        _finishes(lambda: data.fetch("faces/ict/LICENSE"), _free_fifo(folder / "LICENSE"))
    os.unlink(folder / "LICENSE")
    (folder / "LICENSE").mkdir()
    with pytest.raises(DataError, match="folder"):
        data.locate("faces/ict/LICENSE")
    assert data.locate("faces/ict/nothing-here") is None


def test_content_sha256_opens_regular_files_only(tmp_path):
    import os

    (tmp_path / "zero.npz").symlink_to("/dev/zero")  # read forever before the fix
    with pytest.raises(DataError, match="character device"):
        _finishes(lambda: data.content_sha256(tmp_path / "zero.npz"))
    os.mkfifo(tmp_path / "pipe.gz")
    with pytest.raises(DataError, match="FIFO"):
        _finishes(lambda: data.content_sha256(tmp_path / "pipe.gz"), _free_fifo(tmp_path / "pipe.gz"))
    with pytest.raises(DataError, match="folder"):
        data.content_sha256(tmp_path)
    with pytest.raises(DataError, match="no such file"):
        data.content_sha256(tmp_path / "absent")
    with pytest.raises(DataError, match="the file to hash must be a path"):
        data.content_sha256(None)
    with pytest.raises(DataError, match="NUL"):
        data.content_sha256("a\x00b")
    with pytest.raises(DataError, match="NUL"):
        data.locate("faces/ict/LICENSE", root="a\x00b")
    body = b"some content\n" * 100
    (tmp_path / "plain").write_bytes(body)
    with gzip.open(tmp_path / "packed.gz", "wb") as fh:
        fh.write(body)
    want = hashlib.sha256(body).hexdigest()
    assert data.content_sha256(tmp_path / "plain") == data.content_sha256(tmp_path / "packed.gz") == want


def test_content_sha256_bounds_what_a_gz_decompresses(tmp_path, monkeypatch):
    with gzip.open(tmp_path / "bomb.gz", "wb") as fh:
        fh.write(bytes(1 << 20))
    monkeypatch.setattr(data, "MAX_READ_BYTES", 1 << 16)
    with pytest.raises(DataError, match="more than 65536 bytes"):
        data.content_sha256(tmp_path / "bomb.gz")


def test_open_file_names_the_file_and_reads_only_regular_files(private_dir):
    import os

    body = b"MIT License\n"
    entry = data.DataFile("ict", "faces/ict/LICENSE", hashlib.sha256(body).hexdigest(), "")
    folder = private_dir / "faces" / "ict"
    folder.mkdir(parents=True)
    with gzip.open(folder / "LICENSE.gz", "wb") as fh:
        fh.write(body)
    import unittest.mock

    with unittest.mock.patch.dict(data.registry(), {entry.path: entry}):
        fh = data.open_file(entry.path)
        raw = fh.fileobj
        with fh:
            assert fh.read() == body and str(fh.name).endswith("LICENSE.gz")
    assert raw.closed  # the gzip reader closed the file it read from
    os.mkfifo(folder / "other")
    with pytest.raises(DataError, match="FIFO"):
        data._open_raw(folder / "other")


@pytest.mark.parametrize("call", [
    lambda: data.files(["ict"]), lambda: data.files(None), lambda: data.status({}),
    lambda: data.missing_reason(3), lambda: data.missing_reason(["ict"]), lambda: data.require(b"ict"), lambda: data.fetch(["x"]),
    lambda: data.fetch(None), lambda: data.locate(3), lambda: data.locate("x", root=3.5),
    lambda: data.fetch("faces/ict/LICENSE", download="yes"), lambda: data.require("ict", progressbar=None),
    lambda: data.choose("auto", needs="ict"), lambda: data.choose("auto", needs=3),
    lambda: data.choose("auto", needs=[["ict"]]), lambda: data.cache_file(None), lambda: data.cache_writable(3),
])
def test_names_of_the_wrong_type_are_data_errors(private_dir, call):
    with pytest.raises(DataError, match="must be"):
        call()


def test_cache_members_stay_inside_the_cache_folder(tmp_path, monkeypatch):
    cache = tmp_path / "derived"
    (cache / "motion").mkdir(parents=True)
    monkeypatch.setenv("REPRO_CACHE_DIR", str(cache))
    assert data.cache_file("motion/a.npz") == cache.resolve() / "motion" / "a.npz"
    for bad in ("../a.npz", "motion/../../a.npz", "/tmp/a.npz"):
        with pytest.raises(DataError, match="cache file"):
            data.cache_file(bad)
    (tmp_path / "elsewhere").mkdir()
    (cache / "linked").symlink_to(tmp_path / "elsewhere")
    (cache / "motion" / "b.npz").symlink_to(tmp_path / "elsewhere" / "b.npz")
    with pytest.raises(DataError, match="leads outside"):
        data.cache_file("linked/a.npz")
    with pytest.raises(DataError, match="leads outside"):
        data.cache_file("motion/b.npz")
    assert data.cache_writable("motion/b.npz")  # the link itself is replaced by a write, never followed
    assert not data.cache_writable("linked/a.npz")  # a folder leading out is never written into
    assert not data.cache_writable("../a.npz")
