"""The tool's key pair: RSA 2048, made on first use and kept in its folder (DATA/lti/tool-key.pem, mode 0600).

Platforms fetch the public half from GET /lti/jwks to check what the tool signs: the client assertions of
its access-token requests (services.py) and its deep-linking answers. The key's id (`kid`) is its RFC 7638
thumbprint, so it is the same on every start and from every process that reads the same file.

Rotation (`python -m server.lti rotate-key`, `rotate`): the old key's public half goes to DATA/lti/retired-keys.json
with the time it is dropped (now + the grace period), then a new key replaces the file. /lti/jwks publishes the
new key and every retired one until its time, so a platform that cached the old set still checks what was signed
just before; the tool signs with the new key at once. A running server sees the new file at its next signature
or key set (it looks at the file's identity each time).
"""

from __future__ import annotations

import json
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

from joserfc import jwt
from joserfc.jwk import RSAKey

KEY_FILE = "tool-key.pem"
RETIRED_FILE = "retired-keys.json"
KEY_BITS = 2048
ALG = "RS256"
DEFAULT_GRACE_HOURS = 72.0  # how long a retired key stays published (platforms cache key sets for hours)


class ToolKeys:
    """The tool's RSA key pair in `folder`: loaded from its file, or made and written there the first time."""

    def __init__(self, folder: Path, clock: Callable[[], float] = time.time):
        self.folder = Path(folder)
        self.path = self.folder / KEY_FILE
        self.retired_path = self.folder / RETIRED_FILE
        self.clock = clock  # Unix time: when a retired key is dropped
        self._key: RSAKey | None = None
        self._seen: tuple[int, int] | None = None  # the key file's (inode, mtime) when it was loaded
        self._lock = threading.Lock()

    def _identity(self) -> tuple[int, int] | None:
        try:
            st = self.path.stat()
        except FileNotFoundError:
            return None
        return st.st_ino, st.st_mtime_ns

    @property
    def key(self) -> RSAKey:
        with self._lock:
            if self._key is None or self._identity() != self._seen:  # made, or rotated by another process
                self._key = self._load() or self._make()
                self._seen = self._identity()
        return self._key

    @property
    def kid(self) -> str:
        return self.key.thumbprint()

    def _load(self) -> RSAKey | None:
        try:
            return self._read()
        except FileNotFoundError:
            return None

    def _read(self) -> RSAKey:
        return RSAKey.import_key(self.path.read_bytes(), {"alg": ALG, "use": "sig"})

    def _make(self) -> RSAKey:
        """A new key, written whole with mode 0600 under a temporary name and then linked to its own: of two
        processes that make one at once, the first link wins and the other loads that one."""
        self.folder.mkdir(parents=True, exist_ok=True)
        key = RSAKey.generate_key(KEY_BITS, {"alg": ALG, "use": "sig"}, private=True)
        tmp = self.folder / f".{os.getpid()}.{threading.get_ident()}.key.tmp"
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(key.as_pem(private=True))
                f.flush()
                os.fsync(f.fileno())
            try:
                os.link(tmp, self.path)
            except FileExistsError:
                return self._read()  # the first link's key, there for good
        finally:
            tmp.unlink(missing_ok=True)
        return key

    def _write(self, name: str, data: bytes, mode: int) -> None:
        """`data` into the folder's file `name`, whole: written under a temporary name, then renamed over it."""
        tmp = self.folder / f".{os.getpid()}.{threading.get_ident()}.{name}.tmp"
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, mode)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.folder / name)
        finally:
            tmp.unlink(missing_ok=True)

    def retired(self) -> list[dict]:
        """The retired keys still published: [{"jwk": public key, "until": Unix time}], the dropped ones left out."""
        try:
            entries = json.loads(self.retired_path.read_text())
        except (FileNotFoundError, ValueError):
            return []
        now = self.clock()
        return [e for e in entries if isinstance(e, dict) and isinstance(e.get("jwk"), dict)
                and isinstance(e.get("until"), int | float) and e["until"] > now]  # fmt: skip

    def rotate(self, grace: float) -> tuple[str, str, float]:
        """A new key in place of the current one, whose public half stays published for `grace` seconds:
        (the old kid, the new kid, the time the old one is dropped)."""
        old = self.key
        until = self.clock() + grace
        entry = {"jwk": self._public(old), "until": until}
        kept = [e for e in self.retired() if e["jwk"].get("kid") != entry["jwk"]["kid"]]
        self.folder.mkdir(parents=True, exist_ok=True)
        self._write(RETIRED_FILE, json.dumps([*kept, entry], indent=1).encode(), 0o644)  # before the new key
        new = RSAKey.generate_key(KEY_BITS, {"alg": ALG, "use": "sig"}, private=True)
        self._write(KEY_FILE, new.as_pem(private=True), 0o600)
        with self._lock:
            self._key, self._seen = None, None
        return old.thumbprint(), self.kid, until

    @staticmethod
    def _public(key: RSAKey) -> dict:
        public = key.as_dict(private=False)
        return {"kty": "RSA", "n": public["n"], "e": public["e"], "kid": key.thumbprint(), "alg": ALG, "use": "sig"}

    def jwks(self) -> dict:
        """The public key set: {"keys": [{kty, n, e, kid, alg, use}]}, no private part: the current key, then the
        retired ones still in their grace period."""
        current = self._public(self.key)
        retired = [e["jwk"] for e in self.retired() if e["jwk"].get("kid") != current["kid"]]
        return {"keys": [current, *retired]}

    def sign(self, claims: dict) -> str:
        """`claims` as an RS256 JWT with the key's `kid` in its header."""
        return jwt.encode({"alg": ALG, "kid": self.kid, "typ": "JWT"}, claims, self.key, algorithms=[ALG])
