"""The page's pure modules (no DOM: jsonpos.js, edits.js, vec.js, share.js, ...) tested by Node's own test runner
(tests/js/*.test.mjs), in milliseconds rather than through Chromium. One pytest test runs them all, so that
`./dev test` runs them and CI counts them; it fails with node's report. `node --test tests/js/` runs them alone."""

from __future__ import annotations

import shutil
import subprocess

from tests.support.scene import TESTS

JS = TESTS / "js"


def node_test(folder) -> subprocess.CompletedProcess:
    node = shutil.which("node")
    assert node, "node is missing: the page's modules are tested with `node --test` (Node 20 or later)"
    version = subprocess.run([node, "--version"], capture_output=True, text=True, timeout=30).stdout.strip()
    major, minor = (int(n) for n in version.lstrip("v").split(".")[:2])
    assert (major, minor) >= (20, 10), f"node {version}: the tests of tests/js/ need Node 20.10 or later"
    files = sorted(str(p) for p in folder.glob("*.test.mjs"))
    assert files, f"no *.test.mjs in {folder}"
    # the page's modules are ES modules in .js files without a package.json: Node 20 detects their syntax
    argv = [node, "--experimental-detect-module", "--test", "--test-reporter=spec", *files]
    return subprocess.run(argv, capture_output=True, text=True, timeout=120, cwd=folder)


def test_js_pure_modules_pass_node_s_tests():
    r = node_test(JS)
    assert r.returncode == 0, f"node --test failed:\n{r.stdout}\n{r.stderr}"
    # the spec reporter's summary: every test( of the files ran and passed
    declared = sum(p.read_text().count("\ntest(") for p in JS.glob("*.test.mjs"))
    assert f"\u2139 pass {declared}\n" in r.stdout and "\u2139 fail 0\n" in r.stdout, r.stdout


def test_js_a_failing_assertion_fails_the_run(tmp_path):
    """The runner's own check: a .test.mjs whose assertion fails makes the pytest test fail, with node's words."""
    (tmp_path / "bad.test.mjs").write_text(
        'import assert from "node:assert/strict";\nimport { test } from "node:test";\n'
        'test("one", () => assert.equal(1 + 1, 3));\n'
    )
    r = node_test(tmp_path)
    assert r.returncode != 0
    assert "Expected values to be strictly equal" in r.stdout + r.stderr
