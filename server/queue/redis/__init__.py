"""The Redis backend: tries out through RQ to worker hosts anywhere, their events back into the store."""
