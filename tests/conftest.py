"""Shared fixtures: example scenes as dicts, small renders, the repository's paths, and the app in a
TestClient for the API tests (built by test_api_support.api_client; its helpers live there too).

The tests' folders mirror the packages (tracer/, server/api/, server/queue/, ..., web/), and a test
module may use another's helpers by name (`from test_assets import png_uri`, whatever folder either is
in): every folder of tests/ is on the import path from the start (pytest would add each only when it
first collects a file there). Test modules' names are unique across the folders."""

from __future__ import annotations

import copy
import json
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
for _folder in sorted(p for p in TESTS.rglob("*") if p.is_dir() and "__pycache__" not in p.parts):
    if any(_folder.glob("*.py")) and str(_folder) not in sys.path:
        sys.path.append(str(_folder))

ROOT = TESTS.parent
SCENES = ROOT / "scenes"
EXAMPLES = sorted(SCENES.glob("*.json"))


def scene_dict(name: str) -> dict:
    return json.loads((SCENES / f"{name}.json").read_text())


def small(data: dict, width: int = 32, height: int = 24, **sections) -> dict:
    """A copy of a scene dict at a small size, with sections overridden (sampler={...})."""
    d = copy.deepcopy(data)
    d.setdefault("film", {}).update(width=width, height=height)
    for key, values in sections.items():
        if isinstance(values, dict):
            d.setdefault(key, {}).update(values)
        else:
            d[key] = values
    return d


@pytest.fixture(scope="session")
def compiled_kernels():
    """Compile (or load from cache) the renderer's kernels once per test session."""
    from tracer.rendering.progressive import load_kernels

    load_kernels("cpu")
    return True


# -- the service ----------------------------------------------------------------------------------


@pytest.fixture(scope="session")
def client(tmp_path_factory):
    """The app with one real render worker process, shared by the API tests: the worker starts once.
    Each test leaves no job queued or running behind (it waits for its jobs or cancels them). The app has
    an instructor token (test_api_support.INSTRUCTOR), and the client is a student with a token of its own:
    its jobs are its own (test_api_owners.py has the other students)."""
    from test_api_support import INSTRUCTOR, api_client

    with api_client(tmp_path_factory.mktemp("api-data"), workers=1, instructor_token=INSTRUCTOR) as c:
        yield c


@pytest.fixture
def settings(client):
    """The settings of `client`'s app, restored after the test (limits read at submit time can be changed live)."""
    s = client.app.state.settings
    saved = s.model_dump()
    yield s
    for key, value in saved.items():
        setattr(s, key, value)


@pytest.fixture(scope="session")
def client_without_workers(tmp_path_factory):
    """The app with no render worker (submitted jobs wait in the queue), for routes that render nothing;
    a student's client of a server with an instructor token, as `client`."""
    from test_api_support import INSTRUCTOR, api_client

    with api_client(tmp_path_factory.mktemp("api-data-no-workers"), workers=0, instructor_token=INSTRUCTOR) as c:
        yield c
