"""Jobs: their life cycle (statuses, moves, kinds, lanes, how a try ends), the SQLite job store and the job
files, the job service (submit, wait, cancel, estimate, the public view, change events), the janitor
and the examples' previews."""
