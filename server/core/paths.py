"""Where the service finds the repository's own files: the page, the example scenes, the docs."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]  # the checkout: server/core/paths.py -> ../../..
WEB = ROOT / "web"  # the static page, served at /
SCENES = ROOT / "scenes"  # the example scenes (GET /api/scenes)
DOCS = ROOT / "docs"  # the reference pages (GET /reference/)
