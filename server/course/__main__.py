"""python -m server.course publish|roster|grades ...: the instructor's command line (server/course/command.py)."""

from __future__ import annotations

import sys

from server.course.command import main

if __name__ == "__main__":
    sys.exit(main())
