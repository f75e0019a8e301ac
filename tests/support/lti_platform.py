"""The tests' LTI 1.3 platform (an LMS on loopback) and `LoopbackServer`: they live in server/lti/platform.py, where
`python -m server.lti try` plays an LMS with the same platform (one copy); the tests import them from here as
before."""

from __future__ import annotations

from server.lti.platform import (  # noqa: F401  (re-exported for the tests)
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
    START_TIMEOUT,
    LoopbackServer,
    Platform,
    cookies_of,
    free_port,
    member,
    new_key,
    public,
    query_of,
)
