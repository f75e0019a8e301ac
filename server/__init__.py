"""The HTTP service: FastAPI routes over the tracer library (docs/service.md)."""
