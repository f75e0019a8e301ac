"""The embedded backend: render worker processes on the API's host, claiming jobs from the store."""
