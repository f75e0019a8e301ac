"""The checking processes: scene checks in a pool of processes, off the API's event loop (validation, a
pixel's samples, large bodies' JSON)."""
