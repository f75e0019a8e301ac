"""axe-core's WCAG 2.1 AA checks on a page in Chromium (tests/web/test_web_axe.py and the page tests that check their
own views)."""

from __future__ import annotations

import json
import re

import pytest

from tests.support.page import SHOTS

TAGS = ["wcag2a", "wcag2aa", "wcag21a", "wcag21aa"]


# and two rules outside those tags that the accessibility review ran (issue #32): an accessible name that
# does not contain the visible label (WCAG 2.5.3, axe marks the rule experimental) and targets smaller than
# 24 x 24 CSS px without room around them (WCAG 2.2's 2.5.8)
RULES = {"label-content-name-mismatch": {"enabled": True}, "target-size": {"enabled": True}}


BLOCKING = ("serious", "critical")


def axe_script() -> str:
    try:
        from axe_playwright_python.base import AXE_SCRIPT
    except ImportError as exc:
        pytest.fail(f"axe-playwright-python is not installed ({exc}); `pip install -e .[test]` installs it")
    return AXE_SCRIPT


def axe(page, context: str | None = None) -> list[dict]:
    """axe-core's WCAG 2.1 A/AA violations of the page as it is now (of `context`, a selector, if given)."""
    if not page.evaluate("() => typeof window.axe === 'object'"):
        page.evaluate(axe_script())
    return page.evaluate(
        "([ctx, tags, rules]) => axe.run(ctx || document,"
        " {runOnly: {type: 'tag', values: tags}, rules, resultTypes: ['violations']})"
        ".then(r => r.violations.map(v => ({id: v.id, impact: v.impact, help: v.help,"
        " targets: v.nodes.map(n => n.target.join(' ')), summary: v.nodes[0]?.failureSummary || ''})))",
        [context, TAGS, RULES],
    )


def assert_accessible(page, where: str, context: str | None = None) -> list[dict]:
    """No serious or critical violation; the minor and moderate ones are returned (and written to the shots)."""
    found = axe(page, context)
    blocking = [v for v in found if v["impact"] in BLOCKING]
    report = "\n".join(
        f"  {v['id']} ({v['impact']}): {v['help']}; {len(v['targets'])} nodes: {v['targets'][:4]}\n"
        f"    {v['summary'][:300]}"
        for v in blocking
    )
    (SHOTS / f"axe-{re.sub(r'[^a-z0-9]+', '-', where.lower())}.json").write_text(json.dumps(found, indent=1))
    assert not blocking, f"axe on {where}: {len(blocking)} serious or critical violations\n{report}"
    return [v for v in found if v["impact"] not in BLOCKING]
