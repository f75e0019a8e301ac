"""The HTTP API: the routes (one file per resource), their request and response models, and their
dependencies. It reaches jobs only through the job service (server/jobs/service.py) and the queue only
through its interface."""
