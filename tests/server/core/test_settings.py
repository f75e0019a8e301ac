"""Settings (server/core/settings.py): the command line, the environment and a settings file, durations and sizes."""

from __future__ import annotations

import pytest


def test_settings_from_the_environment_and_a_file(tmp_path, monkeypatch):
    from server.core.settings import load_settings

    conf = tmp_path / "service.env"
    conf.write_text("TRACER_MAX_SPP=256\nTRACER_MAX_JOB_SECONDS=30\nTRACER_WORKERS=3\n")
    monkeypatch.setenv("TRACER_MAX_SPP", "64")  # the environment wins over the file
    monkeypatch.setenv("TRACER_SETTINGS_FILE", str(conf))
    s = load_settings(workers=2)  # and arguments (the command line) over both
    assert (s.max_spp, s.max_job_seconds, s.workers) == (64, 30.0, 2)
    assert s.limits.max_spp == 64
    with pytest.raises(FileNotFoundError):
        load_settings(tmp_path / "missing.env")


def test_settings_read_durations_and_sizes(monkeypatch):
    from server.core.settings import Settings

    monkeypatch.setenv("TRACER_KEEP_FINISHED", "12h")
    monkeypatch.setenv("TRACER_MAX_DATA_BYTES", "2GiB")
    s = Settings()
    assert (s.keep_finished, s.max_data_bytes) == (43200.0, 2 * 1024**3)
    assert Settings(keep_finished="90", max_data_bytes="500MB").keep_finished == 90.0
    assert Settings(max_data_bytes="500MB").max_data_bytes == 500_000_000
    assert Settings(**s.model_dump(mode="json")).keep_finished == 43200.0  # as the workers receive them
    with pytest.raises(ValueError, match="30m, 12h, 7d"):
        Settings(keep_finished="a week")


def test_settings_the_scene_limits_are_the_rows_of_one_table(monkeypatch):
    """TRACER_MAX_WIDTH ... TRACER_MAX_SOLVE_RAYS are the rows of tracer/limits.py: their defaults the
    library's, their descriptions the table's, and docs/service.md lists each with its default."""
    from server.core.settings import Settings
    from tests.support.scene import ROOT
    from tracer.limits import LIMITS, Limits

    assert Settings().limits == Limits()
    for limit in LIMITS:
        field = Settings.model_fields[limit.name]
        assert (field.default, field.description) == (limit.default, limit.description)
    monkeypatch.setenv("TRACER_MAX_PATCHES", "7")
    assert Settings().limits == Limits(max_patches=7)
    with pytest.raises(ValueError, match="max_texture_pixels"):
        Settings(max_texture_pixels=100_000_000)  # past Pillow's decompression-bomb guard
    rows = (ROOT / "docs" / "service.md").read_text().splitlines()
    for limit in LIMITS:
        (row,) = [line for line in rows if line.startswith("| ") and f"`TRACER_{limit.name.upper()}`" in line]
        assert row.split(" | ")[1] == str(limit.default), row


def test_settings_a_bad_setting_stops_the_server_naming_it_as_given(tmp_path):
    """`python -m server` refuses a bad setting before it starts anything: one line per setting, named as the user
    gave it (the TRACER_ variable, or the command line's option), what was expected, and never the value itself
    (a token) nor pydantic's own wording and links."""
    import os
    import subprocess
    import sys

    from tests.support.scene import ROOT

    env = {**os.environ, "TRACER_INSTRUCTOR_TOKEN": "short-secret"}
    argv = [sys.executable, "-m", "server", "--port", "9", "--workers", "-2", "--data-dir", str(tmp_path / "data")]
    r = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    error = r.stderr.strip().splitlines()[-1]
    assert "TRACER_INSTRUCTOR_TOKEN: the instructor token must be 16 to 512 letters" in error, error
    assert "--workers: Input should be greater than or equal to 0" in error, error
    for unsaid in ("short-secret", "pydantic", "validation error", "type=", "input_value"):
        assert unsaid not in r.stderr, unsaid
    assert not (tmp_path / "data").exists()  # nothing was made


def test_settings_the_start_up_log_says_what_runs():
    """The processes beside the API (`python -m server`'s "serving on" line): the render workers with the
    interactive ones, none of those without general workers, the checking processes, the grading pool."""
    from server.core.settings import Settings

    assert Settings(workers=1, interactive_workers=1, validate_processes=2, grading_processes=4).processes_text() == (
        "2 render worker processes (1 for interactive work only), 2 scene-checking processes, "
        "a grading pool of 4 processes from the first grading run"
    )
    assert (
        Settings(workers=0, validate_processes=1, grading_processes=1)
        .processes_text()
        .startswith("no render worker (jobs wait in the queue), 1 scene-checking process, a grading pool of 1 process")
    )
    redis = Settings(workers=3, redis_url="redis://cache:6379/0").processes_text()
    assert redis.startswith("3 local worker hosts on Redis at redis://cache:6379/0, ")


@pytest.mark.parametrize(
    ("url", "shown"),
    [
        ("redis://:s3cret-pw@db:6379/0", "redis://:***@db:6379/0"),
        ("rediss://tracer:s3cret-pw@db.example.edu:6380/1", "rediss://tracer:***@db.example.edu:6380/1"),
        ("redis://user:p@ss:w@db/0", "redis://user:***@db/0"),  # an @ in the password
        ("redis://s3cret-pw@db/0", "redis://***@db/0"),  # redis-py reads a lone user part as a password too
        ("redis://db:6379/0?password=s3cret-pw&db=1", "redis://db:6379/0?password=***&db=1"),
        ("unix:///run/redis.sock?password=s3cret-pw", "unix:///run/redis.sock?password=***"),
        ("redis://db:6379/0", "redis://db:6379/0"),
        (None, None),
    ],
)
def test_settings_a_url_is_shown_without_its_password(url, shown):
    from server.core.credentials import masked
    from server.core.settings import Settings

    assert masked(url) == shown
    if url and url.startswith("redis"):
        assert "s3cret" not in Settings(workers=1, redis_url=url).processes_text()


def test_settings_the_redis_url_from_a_file(tmp_path, monkeypatch):
    """TRACER_REDIS_URL_FILE (python -m server --redis-url-file): the URL is the file's first line, so that its
    password is on no command line; the URL and the file both given, a missing or empty file: each refused, naming
    the setting and never the URL. Settings passed on whole (to the workers) keep it."""
    from pydantic import ValidationError

    from server.core.settings import Settings, explain

    secret = tmp_path / "redis-url"
    secret.write_text("redis://:s3cret-pw@db:6379/0\n")
    monkeypatch.setenv("TRACER_REDIS_URL_FILE", str(secret))
    s = Settings()
    assert s.redis_url == "redis://:s3cret-pw@db:6379/0"
    assert Settings(**s.model_dump(mode="json")).redis_url == s.redis_url
    for given, words in (
        ({"redis_url": "redis://other:6379/0"}, "given twice"),
        ({"redis_url_file": tmp_path / "missing"}, "TRACER_REDIS_URL_FILE: cannot read"),
    ):
        with pytest.raises(ValidationError) as refused:
            Settings(**given)
        assert words in explain(refused.value) and "s3cret" not in explain(refused.value)
    (tmp_path / "empty").write_text("\n")
    with pytest.raises(ValidationError, match="is empty"):
        Settings(redis_url_file=tmp_path / "empty")
