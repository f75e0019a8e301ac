"""What one client address may do without a known identity: new tokens, and work waiting in the queue.

A caller's identity is known when their token is the instructor's or on some assignment's roster (an open
assignment's join puts them there); anyone else is anonymous, with or without a token of their own. Per client
address (an IPv6 address by its /64, what one host is usually given, so that a host cannot take a fresh address
for each request):

- **New tokens**: those the server issues to the address (POST /api/jobs without one, joining an open
  assignment): at most TRACER_MAX_NEW_TOKENS_PER_ADDRESS in any TRACER_ADDRESS_WINDOW (a sliding window).
- **Waiting work**: the jobs and ray trees of the address's anonymous callers waiting in the queue: at most
  TRACER_MAX_QUEUED_PER_ADDRESS. A token's own share (TRACER_MAX_QUEUED_PER_TOKEN) holds too, and a ray tree
  asked for without a token belongs to its address (`address_owner`), so its share is the address's.
- **Joined identities** (an open assignment's join: a name anyone may type) are not known identities for these
  caps: their waiting work counts against their address like an anonymous caller's. Joins themselves: at most
  TRACER_MAX_JOINS_PER_ADDRESS of one address in any TRACER_ADDRESS_WINDOW (and TRACER_MAX_JOINS_PER_ASSIGNMENT
  per assignment, in the course's store).
- **Failed authentication**: each request whose token was refused where one was needed (not the instructor's for
  an instructor's route, on no roster with TRACER_REQUIRE_IDENTITY) counts against its address; after
  TRACER_MAX_AUTH_FAILURES in TRACER_AUTH_FAILURE_WINDOW the address's requests with a token get a 429 until the
  oldest failure leaves the window (so a token cannot be guessed at the speed of the network).
- **Checks** (POST /api/assignments/{aid}/check) of one token: TRACER_MAX_CHECKS_PER_MINUTE.
- **Open event streams** (`StreamCaps`, every caller but the instructor): TRACER_MAX_STREAMS_PER_TOKEN of one
  token, TRACER_MAX_STREAMS_PER_ADDRESS of one address, and never more than half of TRACER_MAX_CONNECTIONS.
- **Shared networks**: an address in TRACER_SHARED_NETWORKS (a class behind one NAT, a lab) stands for
  TRACER_SHARED_NETWORK_CLIENTS clients: its caps are that many times a single address's.

Past a cap: 429 with Retry-After, naming the setting. Room is taken before the work (a scene check) and given
back when nothing was issued or queued (an invalid scene, an unknown assignment), so a burst cannot pass a cap.

The caps live in memory, in one process: a restart starts every address afresh (the tokens of the last window are
forgotten; jobs queued before it no longer count against their address, though they still count against their
token's share and the queue's). The address is the connection's peer; behind a reverse proxy, the proxy's, unless
uvicorn trusts it (FORWARDED_ALLOW_IPS, by default 127.0.0.1 only) and takes the client's from X-Forwarded-For.
"""

from __future__ import annotations

import ipaddress
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from server.core.errors import TooMany
from server.core.security import token_hash
from server.core.settings import Settings

SWEEP_EVERY = 1024  # calls between two sweeps of every address (expired tokens and emptied entries forgotten)

StillWaiting = Callable[[list[str]], Iterable[str]]  # of these job ids, those still waiting in the queue


def address_key(host: str | None) -> str:
    """The key a client address is counted by: an IPv4 address itself (an IPv4-mapped IPv6 one too), an IPv6
    address by its /64; anything else (a test client's name, a Unix socket's path) as it is."""
    if not host:
        return "unknown"
    try:
        ip = ipaddress.ip_address(host)
    except ValueError:
        return host
    if isinstance(ip, ipaddress.IPv6Address):
        if ip.ipv4_mapped is not None:
            return str(ip.ipv4_mapped)
        return str(ipaddress.ip_network(f"{ip}/64", strict=False))
    return str(ip)


def address_owner(host: str | None) -> str:
    """The owner of the work an address asks for without a token (its ray trees): no token hashes to it, since
    a token has no ':'."""
    return token_hash(f"address:{address_key(host)}")


def parse_networks(text: str) -> list[ipaddress.IPv4Network | ipaddress.IPv6Network]:
    """TRACER_SHARED_NETWORKS: comma-separated networks or single addresses (checked by the settings)."""
    return [ipaddress.ip_network(n.strip(), strict=False) for n in text.split(",") if n.strip()]


@dataclass
class _Waiting:
    ids: list[str] = field(default_factory=list)  # the address's anonymous jobs counted as waiting
    taken: int = 0  # room taken for jobs not queued yet


class Room:
    """Room taken under a cap, given back on leaving the `with` block unless `keep` was called: with the job's
    id for waiting work (it counts until it leaves the queue), without one for a new token."""

    def __init__(self, release: Callable[[str | None, bool], None]):
        self._release, self._kept, self._id = release, False, None

    def keep(self, job_id: str | None = None) -> None:
        self._kept, self._id = True, job_id

    def __enter__(self) -> Room:
        return self

    def __exit__(self, *exc) -> None:
        self._release(self._id, self._kept)


class AddressCaps:
    """The caps of anonymous clients, per address (module docstring); thread-safe. `clock`: seconds (monotonic)."""

    def __init__(self, settings: Settings, clock: Callable[[], float] = time.monotonic):
        self.settings, self.clock = settings, clock
        self.shared = parse_networks(settings.shared_networks)
        self._lock = threading.Lock()
        self._issued: dict[str, deque[float]] = {}  # address -> the times of its new tokens in the window
        self._waiting: dict[str, _Waiting] = {}
        self._calls = self._waits = 0  # new_token's and waiting's calls (their sweeps)
        now = lambda: self.clock()  # noqa: E731 (the caps' clock, which a test may set later)
        self._joins = SlidingWindow(settings.address_window, now)  # joins of open assignments, per address
        self._failures = SlidingWindow(settings.auth_failure_window, now)  # refused tokens, per address
        self._checks = SlidingWindow(60.0, now)  # POST .../check, per token

    def clients(self, host: str | None) -> int:
        """How many clients an address stands for: TRACER_SHARED_NETWORK_CLIENTS in a shared network, else 1."""
        try:
            ip = ipaddress.ip_address(host or "")
        except ValueError:
            return 1
        if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
            ip = ip.ipv4_mapped
        return self.settings.shared_network_clients if any(ip in n for n in self.shared) else 1

    # -- new tokens ----------------------------------------------------------------------------

    def new_token(self, host: str | None) -> Room:
        """Room for one token issued to this address; 429 past TRACER_MAX_NEW_TOKENS_PER_ADDRESS."""
        key, window = address_key(host), self.settings.address_window
        cap = self.settings.max_new_tokens_per_address * self.clients(host)
        with self._lock:
            self._tick()
            now = self.clock()
            times = self._issued.setdefault(key, deque())
            _expire(times, now - window)
            if len(times) >= cap:
                retry = max(1, math.ceil(times[0] + window - now))
                message = (
                    f"this address ({key}) was given {len(times)} new tokens in the last {_duration(window)}, the "
                    f"most it may have (TRACER_MAX_NEW_TOKENS_PER_ADDRESS): keep using the token you were given "
                    f"(the page keeps it), or try again in {retry} s"
                )
                raise TooMany([{"path": "Authorization", "message": message}], retry_after=retry)
            times.append(now)

        def release(_: str | None, kept: bool) -> None:
            if kept:
                return
            with self._lock:
                left = self._issued.get(key)
                if left is not None and now in left:
                    left.remove(now)

        return Room(release)

    # -- waiting work --------------------------------------------------------------------------

    def waiting(self, host: str | None, still_waiting: StillWaiting) -> Room:
        """Room for one more waiting job or ray tree of this address's anonymous callers; 429 past
        TRACER_MAX_QUEUED_PER_ADDRESS. `still_waiting`: the store's answer of which job ids are still queued (it
        is asked outside the lock; a job counted meanwhile is kept). An entry holds at most its cap of ids; a
        sweep (every SWEEP_EVERY calls) forgets those of addresses that have not asked since."""
        key = address_key(host)
        cap = self.settings.max_queued_per_address * self.clients(host)
        with self._lock:
            self._waits += 1
            keys = [key] if self._waits % SWEEP_EVERY else list(self._waiting)  # a sweep: every address's
            asked = {i for k in keys if k in self._waiting for i in self._waiting[k].ids}
        queued = set(still_waiting(sorted(asked))) if asked else set()
        with self._lock:
            for k in keys:
                if k in self._waiting:
                    other = self._waiting[k]
                    other.ids = [i for i in other.ids if i in queued or i not in asked]
                    if not other.ids and not other.taken:
                        del self._waiting[k]
            entry = self._waiting.setdefault(key, _Waiting())
            if len(entry.ids) + entry.taken >= cap:
                message = (
                    f"this address ({key}) already has {len(entry.ids) + entry.taken} jobs waiting without a known "
                    "identity, the most it may have (TRACER_MAX_QUEUED_PER_ADDRESS): wait for one to start, or "
                    "open your assignment's link to work with your own token"
                )
                raise TooMany([{"path": "", "message": message}], retry_after=5)
            entry.taken += 1

        def release(job_id: str | None, kept: bool) -> None:
            with self._lock:
                entry = self._waiting.setdefault(key, _Waiting())
                entry.taken -= 1
                if kept and job_id is not None:
                    entry.ids.append(job_id)
                if not entry.ids and not entry.taken:
                    del self._waiting[key]

        return Room(release)

    # -- joins, failed authentications, checks -------------------------------------------------

    def join(self, host: str | None) -> Room:
        """Room for one join of an open assignment from this address; 429 past TRACER_MAX_JOINS_PER_ADDRESS in
        any TRACER_ADDRESS_WINDOW (given back unless kept: a join refused for another reason costs nothing)."""
        key = address_key(host)
        at = self._joins.take(key, self.settings.max_joins_per_address * self.clients(host))
        if at is None:
            retry = self._joins.retry_after(key)
            message = (
                f"this address ({key}) joined open assignments {self._joins.count(key)} times in the last "
                f"{_duration(self.settings.address_window)}, the most it may (TRACER_MAX_JOINS_PER_ADDRESS): keep "
                f"the link you were given, or try again in {retry} s"
            )
            raise TooMany([{"path": "", "message": message}], retry_after=retry)
        return Room(lambda _, kept: None if kept else self._joins.give_back(key, at))

    def auth_failed(self, host: str | None) -> None:
        """A request from this address sent a token that was not what the route needed (not the instructor's, on
        no roster where one is required)."""
        self._failures.add(address_key(host))

    def auth_held(self, host: str | None) -> bool:
        """Whether this address has had TRACER_MAX_AUTH_FAILURES failed authentications in the last
        TRACER_AUTH_FAILURE_WINDOW (its tokens that are not known to be good are then refused: `auth_allowed`)."""
        return self._failures.count(address_key(host)) >= self.settings.max_auth_failures * self.clients(host)

    def auth_allowed(self, host: str | None) -> None:
        """429 while this address has had TRACER_MAX_AUTH_FAILURES failed authentications in the last
        TRACER_AUTH_FAILURE_WINDOW: its requests with a token that is not known to be good (the instructor's, a
        roster's or a staff member's are: server/api/deps.py) wait until the oldest leaves the window."""
        key = address_key(host)
        if not self.auth_held(host):
            return
        retry = self._failures.retry_after(key)
        message = (
            f"this address ({key}) sent {self._failures.count(key)} tokens that were refused in the last "
            f"{_duration(self.settings.auth_failure_window)} (TRACER_MAX_AUTH_FAILURES): its requests with a token "
            f"are refused for {retry} s; check the token you send (your assignment's link carries yours)"
        )
        raise TooMany([{"path": "Authorization", "message": message}], retry_after=retry)

    def check(self, owner: str) -> None:
        """One check of a submission (POST /api/assignments/{aid}/check) by this token; 429 past
        TRACER_MAX_CHECKS_PER_MINUTE."""
        if self._checks.take(owner, self.settings.max_checks_per_minute) is None:
            retry = self._checks.retry_after(owner)
            message = (
                f"this token checked {self._checks.count(owner)} times in the last minute, the most it may "
                f"(TRACER_MAX_CHECKS_PER_MINUTE): try again in {retry} s"
            )
            raise TooMany([{"path": "", "message": message}], retry_after=retry)

    def counts(self, host: str | None) -> tuple[int, int]:
        """The address's new tokens in the window, and its waiting jobs as last counted (for tests and logs)."""
        key = address_key(host)
        with self._lock:
            times = self._issued.get(key, deque())
            _expire(times, self.clock() - self.settings.address_window)
            entry = self._waiting.get(key)
            return len(times), (len(entry.ids) + entry.taken if entry else 0)

    def _tick(self) -> None:
        """Every SWEEP_EVERY calls: forget the addresses whose tokens have all left the window (the lock held)."""
        self._calls += 1
        if self._calls % SWEEP_EVERY:
            return
        since = self.clock() - self.settings.address_window
        for key in list(self._issued):
            _expire(self._issued[key], since)
            if not self._issued[key]:
                del self._issued[key]


# -- counts in a sliding window --------------------------------------------------------------------


class SlidingWindow:
    """Events per key in the last `window` seconds (joins of an address, failed authentications of an address,
    checks of a token), in memory; thread-safe; `clock`: seconds (monotonic). A sweep every SWEEP_EVERY calls
    forgets the keys whose events have all left the window, so that memory follows the keys now active."""

    def __init__(self, window: float, clock: Callable[[], float]):
        self.window, self.clock = window, clock
        self._lock = threading.Lock()
        self._times: dict[str, deque[float]] = {}
        self._calls = 0

    def take(self, key: str, cap: int) -> float | None:
        """Count one event of `key` unless it already has `cap` in the window: the event's time, or None (full)."""
        with self._lock:
            now, times = self._look(key)
            if len(times) >= cap:
                return None
            times.append(now)
            return now

    def give_back(self, key: str, at: float) -> None:
        """Forget the event `take` counted at `at` (what it was for did not happen)."""
        with self._lock:
            times = self._times.get(key)
            if times is not None and at in times:
                times.remove(at)

    def add(self, key: str) -> None:
        with self._lock:
            self._look(key)[1].append(self.clock())

    def count(self, key: str) -> int:
        with self._lock:
            return len(self._look(key)[1])

    def retry_after(self, key: str) -> int:
        """Whole seconds until the oldest event of `key` leaves the window (at least 1)."""
        with self._lock:
            now, times = self._look(key)
            return max(1, math.ceil(times[0] + self.window - now)) if times else 1

    def _look(self, key: str) -> tuple[float, deque[float]]:
        """(now, the key's times in the window), after a sweep every SWEEP_EVERY calls (the lock held)."""
        now = self.clock()
        self._calls += 1
        if self._calls % SWEEP_EVERY == 0:
            for k in list(self._times):
                _expire(self._times[k], now - self.window)
                if not self._times[k]:
                    del self._times[k]
        times = self._times.setdefault(key, deque())
        _expire(times, now - self.window)
        return now, times


# -- open event streams ----------------------------------------------------------------------------


class StreamCaps:
    """Open event streams (a job's, a submission's) per token and per client address, so that one client cannot
    take the connections the whole class shares (TRACER_MAX_CONNECTIONS): at most TRACER_MAX_STREAMS_PER_TOKEN of
    one token, and TRACER_MAX_STREAMS_PER_ADDRESS of one address (times its clients in TRACER_SHARED_NETWORKS),
    never more than half of TRACER_MAX_CONNECTIONS: the other half is kept for everyone else. The instructor's are
    not counted (the routes ask for room only for others). Thread-safe; in memory, like the other caps."""

    def __init__(self, settings: Settings, caps: AddressCaps):
        self.settings, self.caps = settings, caps
        self._lock = threading.Lock()
        self._tokens: dict[str, int] = {}
        self._addresses: dict[str, int] = {}

    def address_cap(self, host: str | None) -> int:
        reserve = max(1, self.settings.max_connections // 2)
        return min(self.settings.max_streams_per_address * self.caps.clients(host), reserve)

    def open(self, owner: str | None, host: str | None) -> Callable[[], None]:
        """Room for one more open stream of this token (`owner`: its hash; None without one) and address; 429 past
        either cap. The answer gives it back, once (call it when the stream ends)."""
        key, per_token, per_address = address_key(host), self.settings.max_streams_per_token, self.address_cap(host)
        with self._lock:
            if owner is not None and self._tokens.get(owner, 0) >= per_token:
                message = (
                    f"this token already has {self._tokens[owner]} event streams open, the most one token may have "
                    "(TRACER_MAX_STREAMS_PER_TOKEN): close a tab or a stream you no longer follow"
                )
                raise TooMany([{"path": "Authorization", "message": message}], retry_after=STREAM_RETRY)
            if self._addresses.get(key, 0) >= per_address:
                message = (
                    f"this address ({key}) already has {self._addresses[key]} event streams open, the most one "
                    "address may have (TRACER_MAX_STREAMS_PER_ADDRESS; the other connections are kept for others): "
                    "close a tab or a stream you no longer follow"
                )
                raise TooMany([{"path": "", "message": message}], retry_after=STREAM_RETRY)
            if owner is not None:
                self._tokens[owner] = self._tokens.get(owner, 0) + 1
            self._addresses[key] = self._addresses.get(key, 0) + 1
        released = False

        def release() -> None:
            nonlocal released
            with self._lock:
                if released:
                    return
                released = True
                for counts, k in ((self._tokens, owner), (self._addresses, key)):
                    if k is not None and k in counts:
                        counts[k] -= 1
                        if counts[k] <= 0:
                            del counts[k]

        return release

    def counts(self, owner: str | None, host: str | None) -> tuple[int, int]:
        """The streams open now of this token and of this address (for tests and health)."""
        with self._lock:
            return self._tokens.get(owner or "", 0), self._addresses.get(address_key(host), 0)


STREAM_RETRY = 10


def _expire(times: deque[float], since: float) -> None:
    while times and times[0] <= since:
        times.popleft()


def _duration(seconds: float) -> str:
    for unit, size in (("h", 3600), ("min", 60)):
        if seconds >= size and seconds % size == 0:
            return f"{seconds / size:g} {unit}"
    return f"{seconds:g} s"
