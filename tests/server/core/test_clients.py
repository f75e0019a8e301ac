"""The caps of anonymous clients (server/core/clients.py) alone, on the caps' injectable clock: the sliding window
of new tokens, the room given back when nothing was issued, the waiting jobs counted as the store says, shared
networks and IPv6 addresses by their /64. Through a real server: test_api_clients.py."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from server.core.clients import AddressCaps, StreamCaps, address_key, address_owner
from server.core.errors import TooMany
from server.core.security import token_hash
from server.core.settings import Settings
from tests.support.api import Clock


def caps(**settings) -> tuple[AddressCaps, Clock]:
    clock = Clock(1000.0)
    return AddressCaps(Settings(**settings), clock=clock), clock


def take_token(c: AddressCaps, host: str) -> None:
    with c.new_token(host) as room:
        room.keep()


def test_clients_new_tokens_in_a_sliding_window():
    c, clock = caps(max_new_tokens_per_address=2, address_window="10m")
    take_token(c, "10.0.0.1")
    clock.now += 300
    take_token(c, "10.0.0.1")
    clock.now += 200
    with pytest.raises(TooMany) as refused:
        c.new_token("10.0.0.1")
    assert isinstance(refused.value, TooMany)
    assert refused.value.retry_after == 100  # the first token leaves the window 600 s after it came
    message = refused.value.errors[0]["message"]
    assert "TRACER_MAX_NEW_TOKENS_PER_ADDRESS" in message
    assert "10 min" in message
    assert "10.0.0.1" in message
    take_token(c, "10.0.0.2")  # another address
    clock.now += 100
    take_token(c, "10.0.0.1")  # the first one has left the window
    assert c.counts("10.0.0.1") == (2, 0)


def test_clients_a_token_not_issued_is_given_back():
    c, _ = caps(max_new_tokens_per_address=1)
    with pytest.raises(ValueError), c.new_token("10.0.0.1"):
        raise ValueError("an invalid scene")
    with c.new_token("10.0.0.1"):
        pass  # left without keep: nothing issued
    take_token(c, "10.0.0.1")
    with pytest.raises(TooMany):
        c.new_token("10.0.0.1")


def test_clients_waiting_jobs_count_until_the_store_says_they_left_the_queue():
    c, _ = caps(max_queued_per_address=2)
    queued = {"a", "b"}
    still = lambda ids: [i for i in ids if i in queued]  # noqa: E731 (the store's answer)
    for job_id in ("a", "b"):
        with c.waiting("10.0.0.1", still) as room:
            room.keep(job_id)
    with pytest.raises(TooMany) as refused:
        c.waiting("10.0.0.1", still)
    assert isinstance(refused.value, TooMany)
    assert "TRACER_MAX_QUEUED_PER_ADDRESS" in refused.value.errors[0]["message"]
    queued.discard("a")  # it started
    with c.waiting("10.0.0.1", still):
        pass  # room taken and not kept (nothing queued: an invalid scene) is given back
    with c.waiting("10.0.0.1", still) as room:
        with pytest.raises(TooMany):  # room taken but not yet queued counts: a burst cannot pass the cap
            c.waiting("10.0.0.1", still)
        room.keep("c")
    assert c.counts("10.0.0.1") == (0, 2)


def test_clients_a_shared_network_multiplies_the_caps():
    c, _ = caps(max_new_tokens_per_address=1, shared_networks="203.0.113.0/24, 2001:db8::/32", shared_network_clients=3)
    for _ in range(3):
        take_token(c, "203.0.113.9")
        take_token(c, "2001:db8::5")
    for host in ("203.0.113.9", "2001:db8::5"):
        with pytest.raises(TooMany):
            c.new_token(host)
    assert c.clients("203.0.114.1") == 1 and c.clients("::ffff:203.0.113.9") == 3 and c.clients("testclient") == 1


def test_clients_an_ipv6_address_counts_by_its_64():
    assert address_key("2001:db8:1:2:aaaa::1") == address_key("2001:db8:1:2:bbbb::2") == "2001:db8:1:2::/64"
    assert address_key("2001:db8:1:3::1") != address_key("2001:db8:1:2::1")
    assert address_key("::ffff:10.1.2.3") == address_key("10.1.2.3") == "10.1.2.3"
    assert address_key(None) == "unknown" and address_key("testclient") == "testclient"
    c, _ = caps(max_new_tokens_per_address=1)
    take_token(c, "2001:db8:1:2::1")
    with pytest.raises(TooMany):
        c.new_token("2001:db8:1:2::ffff")  # a fresh address of the same /64 is the same client


def test_clients_an_address_owner_is_no_tokens():
    assert address_owner("10.0.0.1") == address_owner("10.0.0.1") != address_owner("10.0.0.2")
    assert address_owner("10.0.0.1") == token_hash("address:10.0.0.1")  # ':' is in no token (security.TOKEN)


def test_clients_settings_refuse_a_network_that_is_not_one():
    with pytest.raises(ValidationError) as e:
        Settings(shared_networks="10.0.0.0/8, class-b")
    assert "shared_networks" in str(e.value)
    assert "'class-b'" in str(e.value)
    assert Settings(shared_networks="10.0.0.0/8,192.168.1.7").shared_networks == "10.0.0.0/8,192.168.1.7"


def test_clients_one_address_s_streams_leave_half_the_connections_to_others():
    """An address's cap of open streams is at most half of TRACER_MAX_CONNECTIONS, a shared network's too; a
    stream's room given back twice counts once."""
    settings = Settings(
        max_connections=10, max_streams_per_address=4, max_streams_per_token=100, shared_networks="10.9.0.0/16"
    )
    streams = StreamCaps(settings, AddressCaps(settings))
    assert streams.address_cap("10.0.0.1") == 4 and streams.address_cap("10.9.1.1") == 5  # 4 x 300, kept to 5
    held = [streams.open(None, "10.9.1.1") for _ in range(5)]
    with pytest.raises(TooMany) as refused:
        streams.open(None, "10.9.1.1")
    assert isinstance(refused.value, TooMany)
    assert "TRACER_MAX_STREAMS_PER_ADDRESS" in str(refused.value.errors)
    held[0]()
    held[0]()  # once only
    assert streams.counts(None, "10.9.1.1") == (0, 4)
    streams.open(None, "10.9.1.1")
    with pytest.raises(TooMany):
        streams.open(token_hash("a token of sixteen+"), "10.9.1.1")
    assert streams.counts(token_hash("a token of sixteen+"), "10.9.1.1") == (0, 5)  # a refusal holds nothing
