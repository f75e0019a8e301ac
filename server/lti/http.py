"""Outbound HTTP with bounds: an answer's body read up to a limit, never more (a platform's key set, a page of
members). The callers turn `TooLarge` and httpx's errors into their own (LaunchError, ServiceError)."""

from __future__ import annotations

import json

import httpx


class TooLarge(Exception):
    """An answer's body went past its limit (bytes)."""


def read_bounded(response: httpx.Response, limit: int) -> bytes:
    """The body of a streamed `response`, at most `limit` bytes (TooLarge past it: the rest is not read)."""
    declared = response.headers.get("content-length")
    if declared and declared.isdigit() and int(declared) > limit:
        raise TooLarge(f"{declared} bytes, more than {limit}")
    body = bytearray()
    for chunk in response.iter_bytes():
        body += chunk
        if len(body) > limit:
            raise TooLarge(f"more than {limit} bytes")
    return bytes(body)


def get_json(
    client: httpx.Client, url: str, limit: int, headers: dict | None = None, timeout: float = 10.0
) -> tuple[httpx.Response, object]:
    """GET `url` with `client`: the response (its body read, at most `limit` bytes, within `timeout` s for each
    wait) and its JSON (None when the status is not 2xx). Raises httpx.HTTPError, TooLarge, or ValueError for a
    2xx body that is not JSON."""
    with client.stream("GET", url, headers=headers, timeout=timeout) as response:
        body = read_bounded(response, limit)
    if not response.is_success:
        return response, None
    return response, json.loads(body)
