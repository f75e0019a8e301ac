"""python -m server.lti register|list|remove|rotate-key|show-tool|try: LTI 1.3 platforms (server/lti/command.py)."""

from __future__ import annotations

import sys

from server.lti.command import main

if __name__ == "__main__":
    sys.exit(main())
