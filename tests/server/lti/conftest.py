"""The LTI tests' fixtures, shared by every module here without an import: the tool (`tool`, the service's app on
loopback, started once per session) and a fresh test platform per test (`platform`). They are defined in
lti_support.py (a module that imports them by name from there still gets its own, as before)."""

from __future__ import annotations

from lti_support import platform, tool  # noqa: F401  (the fixtures, registered here once for the folder)
from scene_support import EXAMPLES, ROOT, SCENES, scene_dict, small  # noqa: F401  (re-exported: see scene_support)
