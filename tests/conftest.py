"""Shared fixtures: example scenes as dicts, small renders, the repository's paths, and the app in a
TestClient for the API tests (built by test_api_support.api_client; its helpers live there too)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
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
    from tracer.render import load_kernels

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
