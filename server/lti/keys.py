"""The tool's key pair: RSA 2048, made on first use and kept in its folder (DATA/lti/tool-key.pem, mode 0600).

Platforms fetch the public half from GET /lti/jwks to check what the tool signs: the client assertions of
its access-token requests (services.py) and its deep-linking answers. The key's id (`kid`) is its RFC 7638
thumbprint, so it is the same on every start and from every process that reads the same file.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

from joserfc import jwt
from joserfc.jwk import RSAKey

KEY_FILE = "tool-key.pem"
KEY_BITS = 2048
ALG = "RS256"


class ToolKeys:
    """The tool's RSA key pair in `folder`: loaded from its file, or made and written there the first time."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self.path = self.folder / KEY_FILE
        self._key: RSAKey | None = None
        self._lock = threading.Lock()

    @property
    def key(self) -> RSAKey:
        with self._lock:
            if self._key is None:
                self._key = self._load() or self._make()
        return self._key

    @property
    def kid(self) -> str:
        return self.key.thumbprint()

    def _load(self) -> RSAKey | None:
        try:
            pem = self.path.read_bytes()
        except FileNotFoundError:
            return None
        return RSAKey.import_key(pem, {"alg": ALG, "use": "sig"})

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
                return self._load()
        finally:
            tmp.unlink(missing_ok=True)
        return key

    def jwks(self) -> dict:
        """The public key set: {"keys": [{kty, n, e, kid, alg, use}]}, no private part."""
        public = self.key.as_dict(private=False)
        entry = {"kty": "RSA", "n": public["n"], "e": public["e"], "kid": self.kid, "alg": ALG, "use": "sig"}
        return {"keys": [entry]}

    def sign(self, claims: dict) -> str:
        """`claims` as an RS256 JWT with the key's `kid` in its header."""
        return jwt.encode({"alg": ALG, "kid": self.kid, "typ": "JWT"}, claims, self.key, algorithms=[ALG])
