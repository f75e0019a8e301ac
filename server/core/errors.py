"""What the services refuse, and why, in their own words: domain errors, no HTTP in them.

Every refusal carries error items, `[{"path", "message"}]` (the JSON path of what is wrong, "" for the whole
request), the one error shape of the service. The kind says what went wrong; server/api/errors.py alone turns
each kind into its answer (a status, `{"errors": [...]}`, Retry-After or a challenge where they apply), so the
course, grading, the jobs and the checkers raise these and never build a response:

    Invalid 422, BadRequest 400, Unauthorized 401, Forbidden 403, NotFound 404, Conflict 409, TooLarge 413,
    Unsupported 415, TooMany 429, ClientGone 499, Unavailable 503, TookTooLong 504
"""

from __future__ import annotations

from typing import Self

from pydantic import BaseModel, Field

Items = list[dict[str, str]]


class ErrorItem(BaseModel):
    path: str = Field(description="JSON path of the offending field ('' for the whole request)")
    message: str


class DomainError(Exception):
    """A refusal: its error items (a plain message is one item at the path ""), and `retry_after` (seconds) where
    asking again later may work."""

    def __init__(self, errors: Items | str, retry_after: int | None = None):
        self.errors = [{"path": "", "message": errors}] if isinstance(errors, str) else list(errors)
        self.retry_after = retry_after
        super().__init__(f"{type(self).__name__}: {self.errors}")

    @classmethod
    def at(cls, path: str, message: str, **kwargs) -> Self:
        """One error at one path: `NotFound.at("id", "no job with id ...")`."""
        return cls([{"path": path, "message": message}], **kwargs)


class Invalid(DomainError):
    """A value that is wrong (a scene, a field, a pixel outside the film), named at its path."""


class BadRequest(DomainError):
    """A request that is malformed as a whole (not a value in it)."""


class Unauthorized(DomainError):
    """No identity, or a token that is not the one needed. `challenge`: the bearer scheme's error code
    ("invalid_token", "invalid_request"; "" for none), which the answer's WWW-Authenticate names."""

    def __init__(self, errors: Items | str, challenge: str = "invalid_token"):
        super().__init__(errors)
        self.challenge = challenge


class Forbidden(DomainError):
    """Known, but not allowed: a TA where an instructor is needed, a deadline passed, no attempts left."""


class NotFound(DomainError):
    """Unknown, or not the caller's (the same refusal: ids are never confirmed)."""


class Conflict(DomainError):
    """The state does not allow it (a course id taken; an image asked for its scene)."""


class TooLarge(DomainError):
    """A part of a request past its size limit."""


class Unsupported(DomainError):
    """A body of a kind the route does not read (not multipart where a class is uploaded)."""


class TooMany(DomainError):
    """Past a cap (the queue, an address's share, a token's streams): `retry_after` seconds says when to ask again."""


class ClientGone(DomainError):
    """The client went away while its request waited: nobody reads the answer (nginx's 499)."""


class Unavailable(DomainError):
    """The service cannot do it now (no worker for the lane, a checking process died, stopping)."""


class TookTooLong(DomainError):
    """The work did not end within its time limit (a ray tree past TRACER_MAX_RAYTREE_SECONDS)."""
