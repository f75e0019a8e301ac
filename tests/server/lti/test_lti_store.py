"""The LTI tables: platforms (validated URLs, upserts), one-time logins, nonces used once."""

from __future__ import annotations

import pytest

from server.core.errors import Invalid
from server.lti.store import LoginRow, LtiStore, PlatformRow

CANVAS = dict(
    issuer="https://canvas.instructure.com", client_id="10000000000001",
    auth_url="https://sso.canvaslms.com/api/lti/authorize_redirect",
    token_url="https://sso.canvaslms.com/login/oauth2/token", jwks_url="https://sso.canvaslms.com/api/lti/security/jwks",
)  # fmt: skip


def test_lti_store_register_upserts_by_issuer_and_client_id(tmp_path):
    store = LtiStore(tmp_path)
    p = store.register(**CANVAS, deployment_ids=["1:abc"], name="Canvas", now=1.0)
    assert len(p["id"]) == 12
    assert p["deployment_ids"] == ["1:abc"]
    assert p["name"] == "Canvas"
    again = store.register(**CANVAS, deployment_ids=["1:abc", "2:def"], now=2.0)
    assert again["id"] == p["id"]
    assert again["deployment_ids"] == ["1:abc", "2:def"]
    assert store.find(CANVAS["issuer"], CANVAS["client_id"])["id"] == p["id"]
    assert store.find(CANVAS["issuer"])["id"] == p["id"]  # the only one of that issuer
    store.register(**{**CANVAS, "client_id": "other"}, deployment_ids=[], now=3.0)
    assert store.find(CANVAS["issuer"]) is None  # two of that issuer: the client id must say which
    assert store.add_deployment(p["id"], "3:ghi")["deployment_ids"] == ["1:abc", "2:def", "3:ghi"]
    assert [x["client_id"] for x in store.platforms()] == [CANVAS["client_id"], "other"]
    assert store.remove(p["id"]) and store.platform(p["id"]) is None and not store.remove(p["id"])


@pytest.mark.parametrize(
    "field, value",
    [("auth_url", "http://lms.example.edu/auth"), ("jwks_url", "ftp://x/jwks"), ("issuer", "not a url"),
     ("token_url", "https:///no-host"), ("auth_url", "https://a;b.example/x")],
)  # fmt: skip
def test_lti_store_register_refuses_a_bad_url_naming_its_field(tmp_path, field, value):
    with pytest.raises(Invalid) as e:
        LtiStore(tmp_path).register(**{**CANVAS, field: value}, deployment_ids=["1"])
    assert isinstance(e.value, Invalid)
    assert [x["path"] for x in e.value.errors] == [field]
    assert "https://" in e.value.errors[0]["message"] or "URL" in e.value.errors[0]["message"]


def test_lti_store_http_is_allowed_on_loopback_only(tmp_path):
    store = LtiStore(tmp_path)
    for host in ("127.0.0.1:8001", "localhost", "[::1]:9000", "127.9.9.9"):
        urls = {k: f"http://{host}/{k}" for k in ("issuer", "auth_url", "token_url", "jwks_url")}
        store.register(**urls, client_id="c", deployment_ids=["d"], allow_private=True)  # (a test platform)
    with pytest.raises(Invalid) as e:
        store.register(**{**CANVAS, "client_id": " "}, deployment_ids=[""])
    assert [x["path"] for x in e.value.errors] == ["client_id", "deployment_ids[0]"]


def test_lti_store_a_login_is_taken_once_and_only_while_fresh(tmp_path):
    store = LtiStore(tmp_path)
    pid = store.register(**CANVAS, deployment_ids=["1"])["id"]
    state, nonce = store.new_login(pid, "https://tool/lti/launch", now=100.0)
    assert len(state) == len(nonce) == 43
    assert state != nonce  # 256 bits each, base64url
    row = store.take_login(state, now=150.0)
    assert (row["platform_id"], row["nonce"], row["target_link_uri"]) == (pid, nonce, "https://tool/lti/launch")
    assert store.take_login(state, now=150.0) is None  # used
    old, _ = store.new_login(pid, "t", now=100.0)
    assert store.take_login(old, now=100.0 + 601) is None  # too old
    assert store.take_login(old, now=100.0) is None  # and gone
    assert store.take_login("unknown", now=100.0) is None


def test_lti_store_rows_are_typed_with_every_column_of_their_tables(tmp_path):
    """`PlatformRow` (server/lti/store.py) names each column of `lti_platforms` and the platform's deployment ids,
    `LoginRow` each column of `lti_logins`; the store's reads return exactly those keys, so that the type checker
    knows the keys the launch, the services and the course's LMS side read."""
    store = LtiStore(tmp_path)

    def columns(table: str) -> set[str]:
        return {r["name"] for r in store.db.execute(f"PRAGMA table_info({table})")}

    assert set(PlatformRow.__required_keys__) == columns("lti_platforms") | {"deployment_ids"}
    assert set(LoginRow.__required_keys__) == columns("lti_logins")
    p = store.register(**CANVAS, deployment_ids=["1"], trust_emails=True)
    assert set(p) == set(PlatformRow.__required_keys__)
    assert p["trust_emails"] is True  # a bool, not the column's 1
    assert set(store.add_deployment(p["id"], "2")) == set(PlatformRow.__required_keys__)
    assert set(store.platform(p["id"])) == set(PlatformRow.__required_keys__)
    assert set(store.find(CANVAS["issuer"])) == set(PlatformRow.__required_keys__)
    assert [set(x) for x in store.platforms()] == [set(PlatformRow.__required_keys__)]
    state, _ = store.new_login(p["id"], "https://tool/lti/launch", now=100.0)
    assert set(store.take_login(state, now=100.0)) == set(LoginRow.__required_keys__)


def test_lti_store_a_nonce_is_used_once_and_pruned_after_its_expiry(tmp_path):
    store = LtiStore(tmp_path)
    assert store.use_nonce("p", "n1", exp=1000.0, now=900.0)
    assert not store.use_nonce("p", "n1", exp=1000.0, now=950.0)  # a replay
    assert store.use_nonce("q", "n1", exp=1000.0, now=950.0)  # another platform's
    store.use_nonce("p", "n2", exp=10_000.0, now=1000.0 + 3601)  # prunes n1
    assert store.db.execute("SELECT COUNT(*) FROM lti_nonces WHERE nonce = 'n1'").fetchone()[0] == 0


def test_lti_store_origins_seen_are_kept_once_and_bounded(tmp_path):
    store = LtiStore(tmp_path)
    pid = store.register(**CANVAS, deployment_ids=["1"])["id"]
    assert store.add_origin(pid, "https://school.example.edu", 1.0)
    assert not store.add_origin(pid, "https://school.example.edu", 2.0)
    for i in range(30):
        store.add_origin(pid, f"https://s{i}.example.edu", 3.0)
    assert len(store.origins_seen()) == 20 and "https://school.example.edu" in store.origins_seen()
    store.remove(pid)
    assert store.origins_seen() == []


@pytest.mark.parametrize(
    "host",
    ["127.0.0.1:8001", "localhost", "[::1]", "10.1.2.3", "192.168.0.10", "172.16.5.5", "169.254.169.254",
     "[fe80::1]", "[fd00::5]", "0.0.0.0", "[::ffff:10.0.0.1]", "tool.localhost"],
)  # fmt: skip
def test_lti_store_a_private_address_needs_allow_private(tmp_path, host):
    """Loopback, link-local (the cloud's metadata address) and private addresses are refused, naming each field,
    unless the registration allows them (a test platform, an LMS on the school's own network)."""
    store = LtiStore(tmp_path)
    scheme = "http" if host in ("127.0.0.1:8001", "localhost", "[::1]", "tool.localhost") else "https"
    urls = {k: f"{scheme}://{host}/{k}" for k in ("issuer", "auth_url", "token_url", "jwks_url")}
    with pytest.raises(Invalid) as e:
        store.register(**urls, client_id="c", deployment_ids=["d"])
    assert [x["path"] for x in e.value.errors] == ["issuer", "auth_url", "token_url", "jwks_url"]
    assert all("--allow-private" in x["message"] for x in e.value.errors), e.value.errors
    assert store.register(**urls, client_id="c", deployment_ids=["d"], allow_private=True)["issuer"] == urls["issuer"]
    with pytest.raises(Invalid) as e:  # a further service origin is held to the same rule
        store.register(**CANVAS, deployment_ids=["1"], service_origins=[f"https://{host}"])
    assert [x["path"] for x in e.value.errors] == ["service_origins[0]"]


def test_lti_store_logins_are_capped_per_address_and_in_all_and_kept_ten_minutes(tmp_path, monkeypatch):
    """A login writes a row: at most MAX_LOGINS_PER_ADDRESS in flight from one address and MAX_LOGINS in all
    (TooManyLogins with the seconds until the oldest is pruned), each pruned 10 minutes after it was made."""
    from server.lti import store as lti_store

    monkeypatch.setattr(lti_store, "MAX_LOGINS_PER_ADDRESS", 3)
    monkeypatch.setattr(lti_store, "MAX_LOGINS", 5)
    store = LtiStore(tmp_path)
    pid = store.register(**CANVAS, deployment_ids=["1"])["id"]
    states = [store.new_login(pid, "t", now=100.0 + i, address="192.0.2.1")[0] for i in range(3)]
    with pytest.raises(lti_store.TooManyLogins) as e:
        store.new_login(pid, "t", now=110.0, address="192.0.2.1")
    assert e.value.retry_after == 591
    assert "192.0.2.1" not in e.value.message  # the oldest goes at 100 + 600
    store.new_login(pid, "t", now=110.0, address="192.0.2.2")
    store.new_login(pid, "t", now=111.0, address="192.0.2.3")
    with pytest.raises(lti_store.TooManyLogins):  # five in all
        store.new_login(pid, "t", now=112.0, address="192.0.2.4")
    assert store.take_login(states[0], now=120.0) is not None  # a launch takes one: room again
    store.new_login(pid, "t", now=121.0, address="192.0.2.1")
    assert store.db.execute("SELECT COUNT(*) FROM lti_logins").fetchone()[0] == 5
    store.new_login(pid, "t", now=100.0 + 2 + 601, address="192.0.2.9")  # those of 100..102 s pruned at 702..
    assert store.db.execute("SELECT COUNT(*) FROM lti_logins").fetchone()[0] == 4
    assert lti_store.LOGIN_KEEP == 600
