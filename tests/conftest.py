"""Shared fixtures: example scenes as dicts, small renders, the repository's paths."""

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
