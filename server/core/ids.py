"""Ids the service hands out (jobs, submissions): unguessable, and recognised before any database or path
sees them."""

from __future__ import annotations

import secrets

ID_ALPHABET = set("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_")


def new_job_id() -> str:
    return secrets.token_urlsafe(16)  # 128 random bits


def looks_like_job_id(text: str) -> bool:
    return 16 <= len(text) <= 64 and set(text) <= ID_ALPHABET
