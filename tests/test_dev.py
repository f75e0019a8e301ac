"""./dev (the entry point of a fresh machine): pip runs on the first start and when pyproject.toml changes,
never on a warm start; `serve` installs without the test extras, `test` with them (issue #25, item 7).

The script runs from a copy in a temporary folder with a fake Python (`PYTHON`, and the .venv/bin/python its
`-m venv` makes): each call writes its arguments to a log and does nothing else, so no real venv is touched
and no package is downloaded. How long a warm start takes is a benchmark figure (BENCHMARKS.md), not a test."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.support.scene import ROOT

FAKE = """#!/usr/bin/env bash
# a stand-in for Python (and ruff, pyright, npm, biome): logs its arguments; `-m venv DIR` makes DIR/bin/python and
# DIR/bin/ruff, `ci` (npm's) node_modules/.bin/biome
echo "$(basename "$0") $*" >>"$DEV_LOG"
if [ "${1:-}" = -m ] && [ "${2:-}" = venv ]; then
    mkdir -p "$3/bin"
    cp "$0" "$3/bin/python"
    cp "$0" "$3/bin/ruff"
    cp "$0" "$3/bin/pyright"
fi
if [ "$(basename "$0")" = npm ] && [ "${1:-}" = ci ]; then
    mkdir -p node_modules/.bin
    cp "$0" node_modules/.bin/biome
fi
"""


@pytest.fixture
def dev(tmp_path):
    """Run the copied ./dev with arguments: (its stderr, the fake commands it ran since the last run)."""
    shutil.copy(ROOT / "dev", tmp_path / "dev")
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    shutil.copy(ROOT / "package-lock.json", tmp_path / "package-lock.json")
    fake = tmp_path / "python3"
    fake.write_text(FAKE)
    fake.chmod(0o755)
    npm = tmp_path / "npm"
    npm.write_text(FAKE)
    npm.chmod(0o755)
    log = tmp_path / "calls.log"
    env = {**os.environ, "PYTHON": str(fake), "NPM": str(npm), "DEV_LOG": str(log)}
    env.pop("TRACER_TEST_PROCESSES", None)  # the script's default (two), whatever the run around this test asks

    def run(*args: str) -> tuple[str, list[str]]:
        log.write_text("")
        done = subprocess.run([str(tmp_path / "dev"), *args], env=env, capture_output=True, text=True, timeout=60)
        assert done.returncode == 0, done.stderr
        return done.stderr, log.read_text().splitlines()

    run.folder = tmp_path
    return run


def pip_installs(calls: list[str]) -> list[str]:
    return [c for c in calls if " -m pip install -q -e " in c]


def test_dev_serve_installs_once_without_the_test_extras(dev):
    said, calls = dev("serve", "--port", "8123")
    assert "dev: installing" in said and "first run, about a minute" in said, said
    assert calls[0].endswith("-m venv .venv"), calls
    assert pip_installs(calls) == ["python -m pip install -q -e ."], calls
    assert calls[-1] == "python -m server --port 8123", calls

    said, calls = dev("serve")  # warm: straight to the server
    assert said == "" and pip_installs(calls) == [], calls
    assert not any("-m pip" in c for c in calls) and calls[-1] == "python -m server", calls


def test_dev_test_installs_the_test_extras_which_serve_then_keeps(dev):
    dev("serve")
    said, calls = dev("test", "-k", "nothing")  # serve's install lacks pytest and ruff: installed now
    assert "[test] extras" in said, said
    assert pip_installs(calls) == ["python -m pip install -q -e .[test]"], calls
    # two processes, each test file whole in one, in the collection's order (the browser's files last)
    pytest = "python -m pytest -n 2 --dist loadfile --no-loadscope-reorder -k nothing"
    npm = "npm ci --no-audit --no-fund --loglevel=error"
    assert calls[-5:] == ["ruff check .", "ruff format --check .", npm, "biome ci --reporter=summary", pytest], calls
    assert "pyright is left to the whole run" in said, said  # a selection: no type check
    for cmd in ("test", "serve"):  # both warm now: the test extras serve too
        _, calls = dev(cmd)
        assert pip_installs(calls) == [], (cmd, calls)
        assert not any(c.startswith("npm ") for c in calls), (cmd, calls)  # biome is there, from the same lock


def test_dev_test_installs_biome_again_when_its_lock_changes(dev):
    said, calls = dev("test")
    assert "installing the page's JS tools" in said, said
    assert calls[-4] == "biome ci --reporter=summary", calls
    # the whole run: the type checker, and beside it a collection that caches the rewritten test modules
    assert sorted(calls[-3:-1]) == ["pyright ", "python -m pytest --collect-only -q -p no:cacheprovider"], calls
    lock: Path = dev.folder / "package-lock.json"
    lock.write_text(lock.read_text() + "\n")  # a new version of biome, say
    said, calls = dev("test")
    assert "installing the page's JS tools" in said, said
    assert "npm ci --no-audit --no-fund --loglevel=error" in calls, calls


def test_dev_installs_again_when_pyproject_changes(dev):
    dev("test")
    pyproject: Path = dev.folder / "pyproject.toml"
    pyproject.write_text(pyproject.read_text() + "\n# a new dependency, say\n")
    said, calls = dev("serve")
    assert "pyproject.toml changed" in said, said
    assert pip_installs(calls) == ["python -m pip install -q -e .[test]"], calls  # what was there stays
    _, calls = dev("serve")
    assert pip_installs(calls) == [], calls
