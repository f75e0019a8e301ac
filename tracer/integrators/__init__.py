"""Integrators: `whitted` (the ray tree) and `path` (path tracing), one `trace` @wp.func each,
dispatched by SceneData.integrator in dispatch.py."""
