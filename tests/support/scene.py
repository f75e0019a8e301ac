"""The repository's paths and the example scenes as dicts, for every test module
(`from tests.support.scene import ROOT, scene_dict, small`)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

TESTS = Path(__file__).resolve().parent.parent
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
