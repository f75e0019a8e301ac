"""The class-statistics tests' assignment and scenes (tests/server/course/test_api_stats.py,
tests/web/test_web_class_stats.py): the course tests' small assignment (tests/support/dashboard.py: the example's
reference scene at 32 x 24, 6 points for a scene) under a name of its own, and a red-sky scene."""

from __future__ import annotations

from tests.support.dashboard import SIZE, small_reference
from tests.support.dashboard import small_spec as dashboard_spec

reference = small_reference  # the example's reference scene at SIZE, 4 spp
__all__ = ["SIZE", "red", "reference", "small_spec"]


def small_spec() -> dict:
    """Validity 1, 'a glass object' 1, 'an area light' 1, psnr 1, pixels 2: 6 points for a scene."""
    return {**dashboard_spec(), "name": "HW 0: statistics"}


def red(glass: bool) -> dict:
    """A red sky (both image tests fail); with or without the glass (its requirement): 3 or 2 points."""
    scene = reference()
    scene["background"] = [1.0, 0.0, 0.0]
    if not glass:
        scene["materials"]["glass"] = {"kd": 0.5}
    return scene
