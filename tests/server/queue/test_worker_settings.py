"""The worker host (`python -m server.worker`) reads its settings as the API does, through `Settings`
(server/core/settings.py): the command line, then the environment's TRACER_* variables, then a settings file
(`--settings FILE` or TRACER_SETTINGS_FILE). Its dry start (`--check`) says what it would start with; a bad value is
refused by the name it was given, as the API refuses it."""

from __future__ import annotations

import logging
import os

import pytest

from server.queue.redis import host


@pytest.fixture
def check(monkeypatch, caplog):
    """Run the host's `--check` in this process, with no TRACER_* variable but those a test sets: its line."""
    for name in [n for n in os.environ if n.startswith("TRACER_")]:
        monkeypatch.delenv(name)
    caplog.set_level(logging.INFO, logger=host.__name__)

    def run(*argv: str) -> str:
        caplog.clear()
        assert host.main([*argv, "--check"]) == 0
        (line,) = [r.getMessage() for r in caplog.records if r.getMessage().startswith("check: ")]
        return line

    return run


def test_worker_settings_come_from_the_environment_and_a_settings_file(check, monkeypatch, tmp_path):
    settings = tmp_path / "tracer.env"
    settings.write_text(
        f"TRACER_REDIS_URL=redis://:s3cret@127.0.0.1:6390/0\nTRACER_CACHE_DIR={tmp_path / 'solutions'}\n"
    )
    monkeypatch.setenv("TRACER_RENDER_THREADS", "3")
    line = check("--settings", str(settings))
    assert "3 thread(s)" in line, line
    assert f"radiosity cache in {tmp_path / 'solutions'}" in line, line
    assert "redis://:***@127.0.0.1:6390/0" in line, line
    assert "s3cret" not in line
    monkeypatch.setenv("TRACER_SETTINGS_FILE", str(settings))  # the file named by the environment, as the API's
    assert "3 thread(s)" in check()


def test_worker_settings_the_command_line_comes_first(check, monkeypatch, tmp_path):
    """An option wins over its TRACER_ variable; a URL on the command line over the environment's URL file (never
    "given twice" for a URL given once on the command line)."""
    url_file = tmp_path / "redis-url"
    url_file.write_text("redis://:from-the-file@127.0.0.1:6391/0\n")
    monkeypatch.setenv("TRACER_REDIS_URL_FILE", str(url_file))
    monkeypatch.setenv("TRACER_RENDER_THREADS", "3")
    monkeypatch.setenv("TRACER_CACHE_DIR", str(tmp_path / "env-cache"))
    assert "redis://:***@127.0.0.1:6391/0" in check()  # the environment's file read
    line = check("--redis", "redis://127.0.0.1:6392/0", "--threads", "2", "--cache-dir", str(tmp_path / "mine"))
    assert "2 thread(s)" in line and "from redis://127.0.0.1:6392/0" in line, line
    assert f"radiosity cache in {tmp_path / 'mine'}" in line, line
    monkeypatch.delenv("TRACER_REDIS_URL_FILE")
    monkeypatch.setenv("TRACER_REDIS_URL", "redis://127.0.0.1:6393/0")
    assert "redis://:***@127.0.0.1:6391/0" in check("--redis-url-file", str(url_file))


@pytest.mark.parametrize(
    ("argv", "env", "words"),
    [
        ((), {"TRACER_REDIS_URL": "redis://127.0.0.1:6390/0", "TRACER_RENDER_THREADS": "-1"}, "TRACER_RENDER_THREADS"),
        (("--threads", "-1"), {"TRACER_REDIS_URL": "redis://127.0.0.1:6390/0"}, "--threads"),
        (("--settings", "/nonexistent/tracer.env"), {}, "settings file not found"),
        ((), {}, "the Redis URL is missing"),
    ],
    ids=["env", "option", "settings-file", "no-url"],
)
def test_worker_settings_a_bad_one_is_refused_by_its_name(argv, env, words, check, monkeypatch, capsys):
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    with pytest.raises(SystemExit) as exited:
        check(*argv)
    assert exited.value.code == 2
    err = capsys.readouterr().err
    assert words in err, err
    assert "Traceback" not in err
