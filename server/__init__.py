"""The HTTP service: FastAPI routes over the tracer library (DESIGN.md, "HTTP")."""
