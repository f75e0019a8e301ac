"""Secrets as the settings keep and show them: a URL's password masked wherever it is shown (`masked`), a secret
read from a file rather than a command line or the environment (`secret_from_file`, the Redis URL's
`redis_url_from`), the instructor token's strength (`weak_token`), and whether an address to listen on is
loopback only, where a weak token is a warning rather than a refusal (server/core/settings.py,
server/core/security.py)."""

from __future__ import annotations

import ipaddress
import math
import os
import re
from pathlib import Path

MASK = "***"
QUERY_PASSWORD = re.compile(r"(?i)([?&]password=)[^&#]*")


def masked(url: str | None) -> str | None:
    """A URL as it may be shown (logs, /api/health, errors): its password, in its user part or in its query
    (`?password=`), replaced by ***. `redis://:s3cret@db:6379/0` -> `redis://:***@db:6379/0`."""
    if not url:
        return url
    scheme, sep, rest = url.partition("://")
    if not sep:
        return _query_masked(url)
    end = min((i for i in (rest.find(c) for c in "/?#") if i >= 0), default=len(rest))
    netloc, tail = rest[:end], rest[end:]
    userinfo, at, hostport = netloc.rpartition("@")
    if at and ":" in userinfo:
        netloc = f"{userinfo.partition(':')[0]}:{MASK}@{hostport}"
    elif at and userinfo and scheme.lower().startswith("redis"):  # redis://secret@host: redis-py's password
        netloc = f"{MASK}@{hostport}"
    return f"{scheme}://{netloc}{_query_masked(tail)}"


def _query_masked(text: str) -> str:
    return QUERY_PASSWORD.sub(lambda m: m[1] + MASK, text)


def secret_from_file(path: str | os.PathLike, name: str) -> str:
    """A secret kept in a file (its first line, without surrounding white space), so that it is never on a
    command line (where `ps` shows it) nor in the environment; a ValueError naming the setting `name`."""
    try:
        lines = Path(path).read_text().strip().splitlines()
    except OSError as e:
        raise ValueError(f"{name}: cannot read {path}: {e.strerror or e}") from None
    if not lines or not lines[0].strip():
        raise ValueError(f"{name}: the file {path} is empty")
    return lines[0].strip()


def redis_url_from(url: str | None, url_file: str | os.PathLike | None) -> str | None:
    """The Redis URL given as itself (--redis, TRACER_REDIS_URL) or in a file (--redis-url-file,
    TRACER_REDIS_URL_FILE): one of the two, never both."""
    if url and url_file:
        raise ValueError(
            "the Redis URL is given twice: give either TRACER_REDIS_URL (--redis) or TRACER_REDIS_URL_FILE "
            "(--redis-url-file), not both"
        )
    return secret_from_file(url_file, "TRACER_REDIS_URL_FILE") if url_file else url or None


MIN_TOKEN_LENGTH = 24  # the instructor's token: at least this many characters ...
MIN_TOKEN_BITS = 96  # ... and about this many bits, by `token_bits`
TOKEN_CLASSES = ("abcdefghijklmnopqrstuvwxyz", "ABCDEFGHIJKLMNOPQRSTUVWXYZ", "0123456789", "-._~+/=")


def token_bits(text: str) -> float:
    """A simple estimate of a token's strength: its length times log2 of the characters of the kinds it uses
    (lower case, upper case, digits, -._~+/=), as if each were drawn at random from them; a token of fewer than 8
    distinct characters (`aaaa...`, `abab...`) is drawn from no more than those."""
    pool = sum(len(kind) for kind in TOKEN_CLASSES if any(c in kind for c in text))
    if len(set(text)) < 8:
        pool = min(pool, len(set(text)))
    return len(text) * math.log2(pool) if pool > 1 else 0.0


def weak_token(text: str) -> str | None:
    """Why the instructor's token is too weak to guard a server others reach (None: strong enough)."""
    if len(text) < MIN_TOKEN_LENGTH:
        return f"it has {len(text)} characters, fewer than {MIN_TOKEN_LENGTH}"
    bits = token_bits(text)
    if bits < MIN_TOKEN_BITS:
        return f"it is worth about {bits:.0f} bits, fewer than {MIN_TOKEN_BITS} (too few kinds of characters)"
    return None


STRONG_TOKEN = 'python -c "import secrets; print(secrets.token_urlsafe(32))" makes a strong one'


def loopback_address(host: str) -> bool:
    """Does an address to listen on reach this machine only (server/core/security.py's `loopback_only`)?"""
    name = host.strip().strip("[]").lower().rstrip(".")
    try:
        return name == "localhost" or ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False
