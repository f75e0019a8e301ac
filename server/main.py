"""The FastAPI application: API routers under /api, the static page from web/ at /."""

from __future__ import annotations

import logging
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.staticfiles import StaticFiles

from server.routes import scenes, tools
from server.settings import Settings

WEB = Path(__file__).resolve().parent.parent / "web"
log = logging.getLogger("server")


@asynccontextmanager
async def lifespan(app: FastAPI):
    """Compile (or load from Warp's cache) the kernels at start-up, never in a user's request."""
    import warp as wp

    from tracer.integrators import whitted

    wp.load_module(whitted, device="cpu")
    log.info("render kernels ready")
    yield


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings()
    app = FastAPI(
        title="Ray tracing for teaching",
        version="0.1.0",
        lifespan=lifespan,
        description="Submit scenes, render them with Warp, inspect the ray tree of any pixel.",
    )
    app.state.settings = settings

    @app.exception_handler(RequestValidationError)
    async def request_errors(request: Request, exc: RequestValidationError):
        errs = [{"path": ".".join(str(p) for p in e["loc"] if p != "body"), "message": e["msg"]} for e in exc.errors()]
        return JSONResponse({"errors": errs}, status_code=422)

    app.include_router(tools.router)
    app.include_router(scenes.router)
    app.mount("/", StaticFiles(directory=WEB, html=True), name="web")
    return app
