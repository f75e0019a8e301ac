"""The tests' LTI 1.3 platform (an LMS on loopback) and `LoopbackServer`: they live in server/lti/ (platform.py,
platform_services.py, loopback.py), where `python -m server.lti try` plays an LMS with the same platform (one
copy); the tests import them from here as before."""

from __future__ import annotations

from server.lti.loopback import START_TIMEOUT, LoopbackServer, free_port  # noqa: F401  (re-exported for the tests)
from server.lti.platform import Platform, cookies_of, new_key, query_of  # noqa: F401
from server.lti.platform_services import (  # noqa: F401
    AGS,
    AGS_CLAIM,
    AGS_SCOPES,
    CONTEXT,
    DL,
    INSTRUCTOR,
    LEARNER,
    LINEITEM_TYPE,
    LINEITEMS_TYPE,
    LTI,
    MEMBERS_TYPE,
    NRPS_SCOPE,
    member,
    public,
)
