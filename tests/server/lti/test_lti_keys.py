"""The tool's key pair: made once, kept private (0600), the same kid on every load; a JWKS of public parts."""

from __future__ import annotations

import os
import stat
import threading
import time

from joserfc import jwt
from joserfc.jwk import KeySet

from server.lti.keys import ToolKeys


def test_lti_keys_made_once_and_reloaded_the_same(tmp_path):
    first = ToolKeys(tmp_path / "lti")
    jwks = first.jwks()
    again = ToolKeys(tmp_path / "lti")
    assert again.kid == first.kid and again.jwks() == jwks
    assert [p.name for p in (tmp_path / "lti").iterdir()] == ["tool-key.pem"]  # no temporary file left
    assert stat.S_IMODE(os.stat(first.path).st_mode) == 0o600


def test_lti_keys_jwks_has_no_private_part_and_verifies_what_it_signs(tmp_path):
    keys = ToolKeys(tmp_path / "lti")
    (entry,) = keys.jwks()["keys"]
    assert set(entry) == {"kty", "n", "e", "kid", "alg", "use"}
    assert (entry["kty"], entry["alg"], entry["use"], entry["e"]) == ("RSA", "RS256", "sig", "AQAB")
    assert len(entry["n"]) >= 342  # 2048 bits in base64url
    token = keys.sign({"hello": "world"})
    decoded = jwt.decode(token, KeySet.import_key_set(keys.jwks()), algorithms=["RS256"])
    assert decoded.header["kid"] == keys.kid
    assert decoded.claims == {"hello": "world"}


def test_lti_keys_made_by_two_threads_at_once_are_one_key(tmp_path):
    made = [ToolKeys(tmp_path / "lti") for _ in range(4)]
    threads = [threading.Thread(target=lambda k=k: k.kid) for k in made]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert len({k.kid for k in made}) == 1


def test_lti_keys_rotation_publishes_both_for_the_grace_period_then_drops_the_old(tmp_path, capsys):
    """`python -m server.lti rotate-key` beside a running server (another ToolKeys on the same folder): the server
    signs with the new key at once, and its key set has the new key and the old one until the grace period ends
    (its clock), then the new one alone."""
    from server.lti.command import main
    from tests.support.api import Clock

    clock = Clock(time.time())  # (the command's clock is the real one)
    server = ToolKeys(tmp_path / "data" / "lti", clock=clock)
    old = server.kid
    signed_before = server.sign({"n": 1})
    assert main(["rotate-key", "--grace-hours", "2", "--data-dir", str(tmp_path / "data")]) == 0
    new = capsys.readouterr().out.splitlines()[0]
    assert new != old
    assert server.kid == new  # the server sees the new file
    assert [k["kid"] for k in server.jwks()["keys"]] == [new, old]
    keys = KeySet.import_key_set(server.jwks())
    assert jwt.decode(signed_before, keys, algorithms=["RS256"]).claims == {"n": 1}  # signed before: still checks
    assert jwt.decode(server.sign({"n": 2}), keys, algorithms=["RS256"]).header["kid"] == new
    assert stat.S_IMODE(os.stat(server.path).st_mode) == 0o600
    assert "BEGIN" not in (tmp_path / "data" / "lti" / "retired-keys.json").read_text()  # public halves only
    clock.now += 2 * 3600 + 1
    assert [k["kid"] for k in server.jwks()["keys"]] == [new]
    assert main(["rotate-key", "--grace-hours", "-1", "--data-dir", str(tmp_path / "data")]) == 1
