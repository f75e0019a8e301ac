"""The tool's key pair: made once, kept private (0600), the same kid on every load; a JWKS of public parts."""

from __future__ import annotations

import os
import stat
import threading

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
    assert decoded.header["kid"] == keys.kid and decoded.claims == {"hello": "world"}


def test_lti_keys_made_by_two_threads_at_once_are_one_key(tmp_path):
    made = [ToolKeys(tmp_path / "lti") for _ in range(4)]
    threads = [threading.Thread(target=lambda k=k: k.kid) for k in made]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert len({k.kid for k in made}) == 1
