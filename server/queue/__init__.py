"""The job queue: one interface (base.py) and two backends beside each other, embedded/ (worker processes
of this host claiming from SQLite) and redis/ (worker hosts through RQ); render_try.py is one try of one
job, the same code on both."""
