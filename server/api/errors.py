"""Every error answer has one shape, `{"errors": [{"path", "message"}]}`, and no error is ever a 500 by accident.
The one place where refusals become HTTP answers (`install_error_handlers`):

- the services' domain errors (server/core/errors.py) by their kind (`STATUS`), with Retry-After where they say
  when to ask again and the bearer challenge of a 401;
- `ApiError`, raised by the routes for what only HTTP has (a status of their own, headers);
- request validation errors (pydantic) are translated to JSON paths of the request body;
- a full disk (the job store's or a file's write) is 507 Insufficient Storage, whatever route met it;
- `SafeJSONResponse` is the app's response class: NaN and Infinity become null, so echoing a bad
  value can never crash the serialisation of its own error message.
"""

from __future__ import annotations

import json
import logging
import math
import sqlite3
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from server.core.errors import (
    BadRequest,
    ClientGone,
    Conflict,
    DomainError,
    Forbidden,
    Invalid,
    NotFound,
    TookTooLong,
    TooLarge,
    TooMany,
    Unauthorized,
    Unavailable,
    Unsupported,
)
from server.core.files import is_disk_full
from tracer.errors import translate_error

log = logging.getLogger("server")
DISK_FULL = (
    "the server's disk is full: nothing of this request was kept; try again later (the server's log says so "
    "to its administrator)"
)
STATUS: dict[type[DomainError], int] = {  # a refusal's kind -> its status (a subclass takes its nearest base's)
    BadRequest: 400, Unauthorized: 401, Forbidden: 403, NotFound: 404, Conflict: 409, TooLarge: 413,
    Unsupported: 415, Invalid: 422, TooMany: 429, ClientGone: 499, Unavailable: 503, TookTooLong: 504,
}  # fmt: skip


def status_of(exc: DomainError) -> int:
    return next(STATUS[k] for k in type(exc).__mro__ if k in STATUS)


def headers_of(exc: DomainError) -> dict[str, str] | None:
    """What a refusal says beyond its items: when to ask again (Retry-After), the bearer challenge of a 401."""
    if isinstance(exc, Unauthorized):
        error = f', error="{exc.challenge}"' if exc.challenge else ""
        return {"WWW-Authenticate": f'Bearer realm="tracer"{error}'}
    return {"Retry-After": str(exc.retry_after)} if exc.retry_after is not None else None


def sanitise(value: Any) -> Any:
    """A copy of `value` that JSON can carry: non-finite floats -> None, tuples -> lists, bytes -> text."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): sanitise(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [sanitise(v) for v in value]
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    return value


class SafeJSONResponse(JSONResponse):
    """JSON that never fails on NaN or Infinity (they become null)."""

    def render(self, content: Any) -> bytes:
        return json.dumps(sanitise(content), ensure_ascii=False, allow_nan=False, separators=(",", ":")).encode()


class ApiError(Exception):
    """An answer of a route with a 4xx status and error items, for what only HTTP has (a status no domain error
    names, headers of its own); the services raise domain errors (server/core/errors.py) instead."""

    def __init__(self, status: int, errors: list[dict[str, str]] | str, headers: dict[str, str] | None = None):
        self.status = status
        self.errors = [{"path": "", "message": errors}] if isinstance(errors, str) else list(errors)
        self.headers = headers
        super().__init__(f"{status}: {self.errors}")


def errors_response(status: int, errors: list[dict[str, str]], headers: dict[str, str] | None = None):
    items = [{"path": str(e.get("path", "")), "message": str(e.get("message", ""))} for e in errors]
    return SafeJSONResponse({"errors": items}, status_code=status, headers=headers)


def _line_col(doc: Any, pos: int) -> str:
    if isinstance(doc, bytes | bytearray):
        doc = doc.decode("utf-8", errors="replace")
    if not isinstance(doc, str) or not 0 <= pos <= len(doc):
        return f"character {pos}"
    line = doc.count("\n", 0, pos) + 1
    col = pos - (doc.rfind("\n", 0, pos) + 1) + 1
    return f"line {line}, column {col}"


# ---------------------------------------------------------------------------------------------
# pydantic's errors about a request -> {path, message}.
#
# The request's own part is here: where an error is (the body, or a query, path or header parameter)
# and errors of the body as a whole (not JSON, not an object). An error at a field is worded by the
# library's one translator (tracer/errors.py), in the words of a scene's errors; a request's model is
# not in FastAPI's error, so it translates without one.

LOCATIONS = ("body", "query", "path", "header")  # where FastAPI says a request's error is
BODY_TYPE_ERRORS = ("model_attributes_type", "dict_type", "model_type")  # a body that is not an object


def is_json_type(content_type: str | None) -> bool:
    """Does a Content-Type header say JSON (application/json, or a +json type), as FastAPI reads it?"""
    kind = (content_type or "").split(";")[0].strip().lower()
    return kind == "application/json" or (kind.startswith("application/") and kind.endswith("+json"))


def not_an_object(content_type: str | None) -> str:
    """The message of a body that did not arrive as a JSON object: its Content-Type is wrong (FastAPI reads a
    body as JSON only when it says so), or the JSON is something else than an object."""
    if content_type is None:
        return "the request has no Content-Type header: expected 'Content-Type: application/json'"
    if not is_json_type(content_type):
        shown = content_type.split(";")[0].strip()[:100]
        return f"the Content-Type is '{shown}', not JSON: expected 'Content-Type: application/json'"
    return "the body must be a JSON object {...}"


def translate_request_errors(exc: RequestValidationError, content_type: str | None = None) -> list[dict[str, str]]:
    """pydantic's errors about a request -> [{path, message}] with JSON paths inside the body (`content_type`:
    the request's Content-Type header, which a body that is not an object may have wrong)."""
    out = []
    for err in exc.errors():
        loc = list(err.get("loc") or ())
        where = loc.pop(0) if loc and loc[0] in LOCATIONS else "body"
        kind = err.get("type", "")
        if kind == "json_invalid":
            pos = loc[0] if loc and isinstance(loc[0], int) else 0
            error = (err.get("ctx") or {}).get("error", "decode error")
            message = f"invalid JSON at {_line_col(getattr(exc, 'body', None), pos)}: {error}"
            out.append({"path": "", "message": message})
        elif kind == "missing" and not loc:
            out.append({"path": "", "message": "a JSON object body is required"})
        elif kind in BODY_TYPE_ERRORS and not loc and where == "body":
            out.append({"path": "", "message": not_an_object(content_type)})
        else:
            item = translate_error({**err, "loc": tuple(loc)})
            if where != "body" and item["path"]:
                item["message"] += f" (in the {where} parameter '{item['path']}')"
            out.append(item)
    return out or [{"path": "", "message": "invalid request"}]


def not_text(exc: UnicodeDecodeError) -> str:
    """The message of a JSON body that is not UTF-8: the first byte that is not, by its offset in the body."""
    where = f"byte 0x{exc.object[exc.start]:02x} at offset {exc.start}" if exc.start < len(exc.object) else "its end"
    encoding = "UTF-8" if exc.encoding.replace("-", "").lower() == "utf8" else exc.encoding.upper()
    return f"the body is not {encoding} text: {where} ({exc.reason}); JSON must be sent as UTF-8"


def install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(DomainError)
    async def refused(request: Request, exc: DomainError):
        return errors_response(status_of(exc), exc.errors, headers_of(exc))

    @app.exception_handler(ApiError)
    async def api_error(request: Request, exc: ApiError):
        return errors_response(exc.status, exc.errors, exc.headers)

    @app.exception_handler(RequestValidationError)
    async def request_errors(request: Request, exc: RequestValidationError):
        return errors_response(422, translate_request_errors(exc, request.headers.get("content-type")))

    @app.exception_handler(StarletteHTTPException)
    async def http_errors(request: Request, exc: StarletteHTTPException):
        detail = exc.detail if isinstance(exc.detail, str) else json.dumps(sanitise(exc.detail))
        if exc.status_code == 400 and detail == "There was an error parsing the body":
            cause = exc.__cause__  # what json.loads raised (FastAPI's `raise ... from`)
            if isinstance(cause, UnicodeDecodeError):
                detail = not_text(cause)
            else:
                detail = "the body could not be parsed as JSON (a number too long, or nesting too deep)"
        return errors_response(exc.status_code, [{"path": "", "message": detail}], getattr(exc, "headers", None))

    @app.exception_handler(OSError)
    @app.exception_handler(sqlite3.Error)
    async def storage_error(request: Request, exc: Exception):
        """A full disk is 507, with nothing of the request kept (the job store's writes are transactions, its
        files are written whole or not at all); any other storage error is the 500 of a bug."""
        if is_disk_full(exc):
            log.warning("%s %s: the data directory's disk is full (%s)", request.method, request.url.path, exc)
            return errors_response(507, [{"path": "", "message": DISK_FULL}], {"Retry-After": "60"})
        return await crashed(request, exc)

    @app.exception_handler(Exception)
    async def crashed(request: Request, exc: Exception):
        log.exception("unhandled error in %s %s", request.method, request.url.path)
        return errors_response(500, [{"path": "", "message": "internal error (logged on the server)"}])
