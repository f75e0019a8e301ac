"""Grading runs on the service: their rows, their thread, the grading processes, and classes uploaded as
multipart streams."""
