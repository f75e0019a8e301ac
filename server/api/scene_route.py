"""Routes whose body carries a scene: a large body's JSON is parsed in a checking process, not on the event
loop (`scene_post`)."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, Request, Response
from fastapi.routing import APIRoute

from server.api.errors import headers_of, status_of
from server.checkers.tasks import loaded, read
from server.core.errors import DomainError

READ_HERE = 65536  # bytes: a request body smaller than this is parsed in the API process (in well under 1 ms)


class SceneRequest(Request):
    """The request of a route whose body carries a scene: a large body's JSON is parsed in a checking process,
    not on the event loop (1.6 MB of spheres took 30-50 ms to parse here), and the route's model sees the
    body with an empty scene (`read`; a small body is parsed here, the same way). The route sends the
    request's bytes to be checked (`CheckPool.summary`, ...) and never reads `scene` from its model."""

    async def json(self):
        if not hasattr(self, "_json"):
            body = await self.body()
            if len(body) < READ_HERE:
                self._json = loaded(read(body), body)
            else:
                try:
                    self._json = await self.app.state.checks.read(self.is_disconnected, body)
                except DomainError as exc:  # FastAPI would answer anything else raised here with a 400
                    raise HTTPException(status_of(exc), exc.errors[0]["message"], headers_of(exc)) from None
        return self._json


class SceneRoute(APIRoute):
    """A route whose request is a `SceneRequest` (FastAPI's custom route class)."""

    def get_route_handler(self):
        handler = super().get_route_handler()

        async def route(request: Request) -> Response:
            return await handler(SceneRequest(request.scope, request.receive))

        return route


def scene_post(router: APIRouter, path: str, **options):
    """`@router.post(path, **options)` for a route whose body carries a scene: its request is a SceneRequest."""

    def decorator(endpoint):
        router.add_api_route(path, endpoint, methods=["POST"], route_class_override=SceneRoute, **options)
        return endpoint

    return decorator
