"""Educational ray tracer on NVIDIA Warp: Whitted ray trees, distribution ray tracing and radiosity."""
