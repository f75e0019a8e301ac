"""The course's tables in DATA/jobs.sqlite3 (what each keeps: server/course/store.py's docstring): the schema of a
new database; an existing one gets its changes as numbered migrations (server/core/migrations.py)."""

from __future__ import annotations

from typing import Any, TypedDict

SCHEMA = """
CREATE TABLE IF NOT EXISTS courses (
    id TEXT PRIMARY KEY,                  -- 1 to 40 letters, digits, '-' or '_' (in URLs: /api/courses/{id})
    name TEXT NOT NULL,
    created_at REAL NOT NULL,             -- Unix time (s), the API's clock
    late_tokens INTEGER NOT NULL DEFAULT 0 -- late tokens (days) each student starts with (server/course/tokens.py)
);
CREATE TABLE IF NOT EXISTS course_staff (
    course_id TEXT NOT NULL,
    person TEXT NOT NULL,                 -- an id like a roster's
    name TEXT NOT NULL,
    email TEXT NOT NULL DEFAULT '',
    role TEXT NOT NULL,                   -- instructor or ta
    lti_user TEXT,                        -- '<platform id>:<sub>' when they came from an LMS launch
    gen INTEGER NOT NULL DEFAULT 0,       -- their token's generation (a new link: + 1, the old one stops working)
    created_at REAL NOT NULL,
    PRIMARY KEY (course_id, person)
);
CREATE TABLE IF NOT EXISTS course_members (
    course_id TEXT NOT NULL,
    student TEXT NOT NULL,                -- the roster's id
    name TEXT NOT NULL,
    email TEXT NOT NULL DEFAULT '',
    self_declared INTEGER NOT NULL DEFAULT 0, -- joined an open assignment by a name they typed
    every INTEGER NOT NULL DEFAULT 0,     -- on every assignment's roster (the course's roster, an LMS's)
    lti_user TEXT,                        -- '<platform id>:<sub>' when known to an LMS
    gen INTEGER NOT NULL DEFAULT 0,       -- their token's generation
    created_at REAL NOT NULL,
    left_at REAL,                         -- the LMS's roster no longer had them (inactive: kept, cannot submit)
    PRIMARY KEY (course_id, student)
);
CREATE INDEX IF NOT EXISTS course_members_lti ON course_members (course_id, lti_user);
CREATE TABLE IF NOT EXISTS course_tokens (
    token_hash TEXT PRIMARY KEY,          -- SHA-256 (hex) of a token: also the owner of its workspace jobs
    course_id TEXT NOT NULL,
    kind TEXT NOT NULL,                   -- student or staff
    person TEXT NOT NULL,                 -- course_members.student or course_staff.person
    created_at REAL NOT NULL
);
CREATE INDEX IF NOT EXISTS course_tokens_person ON course_tokens (course_id, kind, person);
CREATE TABLE IF NOT EXISTS course_assignments (
    id TEXT PRIMARY KEY,                  -- 32 hex digits (an open assignment's link carries it)
    version INTEGER NOT NULL,             -- the current version (1, 2, ...)
    created_at REAL NOT NULL,             -- Unix time (s), the API's clock
    course_id TEXT NOT NULL DEFAULT 'default'
);
CREATE TABLE IF NOT EXISTS course_versions (
    assignment_id TEXT NOT NULL,
    version INTEGER NOT NULL,
    spec TEXT NOT NULL,                   -- the grading spec (JSON, reference scene inline)
    policy TEXT NOT NULL,                 -- deadline, late cut-off and penalty, limits, feedback... (JSON)
    run_id TEXT NOT NULL,                 -- its open grading run (grading_runs.id)
    created_at REAL NOT NULL,
    PRIMARY KEY (assignment_id, version)
);
CREATE TABLE IF NOT EXISTS course_enrolments (
    assignment_id TEXT NOT NULL,
    student TEXT NOT NULL,                -- course_members.student of the assignment's course
    deadline REAL,                        -- their extension (Unix time); NULL: the assignment's
    created_at REAL NOT NULL,
    PRIMARY KEY (assignment_id, student)
);
CREATE TABLE IF NOT EXISTS course_submissions (
    id TEXT PRIMARY KEY,                  -- 32 hex digits
    assignment_id TEXT NOT NULL,
    student TEXT NOT NULL,
    version INTEGER NOT NULL,             -- the version it is graded against
    run_id TEXT NOT NULL,                 -- that version's grading run; its row there is keyed by this id
    kind TEXT NOT NULL,                   -- scene, png or exr
    file TEXT NOT NULL,                   -- relative to DATA/course/
    accepted_at REAL NOT NULL,            -- Unix time (s): the API's clock when its body was accepted
    late INTEGER NOT NULL,                -- after the student's deadline when it came (its view reads the deadline now)
    handed INTEGER NOT NULL DEFAULT 0,    -- its row is in the grading run (a restart hands those that are not)
    tokens_spent INTEGER NOT NULL DEFAULT 0 -- late tokens (days) it spent when it came (server/course/tokens.py)
);
CREATE INDEX IF NOT EXISTS course_submissions_student ON course_submissions (assignment_id, student, accepted_at);
CREATE TABLE IF NOT EXISTS course_token_grants (
    course_id TEXT NOT NULL,
    student TEXT NOT NULL,                -- course_members.student
    added INTEGER NOT NULL,               -- tokens (days) granted
    before INTEGER NOT NULL,              -- the student's tokens left before, and after
    after INTEGER NOT NULL,
    who TEXT NOT NULL,                    -- the staff member's id (or 'admin')
    why TEXT NOT NULL DEFAULT '',
    at REAL NOT NULL                      -- Unix time (s), the API's clock
);
CREATE INDEX IF NOT EXISTS course_token_grants_student ON course_token_grants (course_id, student);
CREATE TABLE IF NOT EXISTS course_extensions (
    assignment_id TEXT NOT NULL,
    student TEXT NOT NULL,
    before REAL,                          -- their own deadline before (NULL: the assignment's), and after
    after REAL,
    who TEXT NOT NULL,                    -- the staff member's id (or 'admin')
    why TEXT NOT NULL DEFAULT '',
    at REAL NOT NULL
);
CREATE INDEX IF NOT EXISTS course_extensions_student ON course_extensions (assignment_id, student);
CREATE TABLE IF NOT EXISTS course_manual_grades (
    submission_id TEXT NOT NULL,          -- course_submissions.id
    item TEXT NOT NULL,                   -- the name of a manual item of the spec
    assignment_id TEXT NOT NULL,
    rubric TEXT NOT NULL,                 -- JSON list of the chosen levels' NAMES (points: the current spec's)
    points REAL,                          -- the grader's override; NULL: the chosen levels' sum
    comment TEXT NOT NULL DEFAULT '',
    grader TEXT,                          -- course_staff.person; NULL: the admin
    graded_at REAL NOT NULL,
    PRIMARY KEY (submission_id, item)
);
CREATE INDEX IF NOT EXISTS course_manual_grades_assignment ON course_manual_grades (assignment_id);
CREATE TABLE IF NOT EXISTS course_manual (
    assignment_id TEXT PRIMARY KEY,       -- an assignment's manual grading (no row: not released, not anonymous)
    released_at REAL,                     -- when the instructor released the manual part; NULL: not yet
    released_by TEXT,
    anonymous INTEGER NOT NULL DEFAULT 0  -- students' names hidden from graders until release
);
CREATE TABLE IF NOT EXISTS course_graders (
    assignment_id TEXT NOT NULL,
    student TEXT NOT NULL,
    grader TEXT NOT NULL,                 -- course_staff.person who grades this student's submission
    PRIMARY KEY (assignment_id, student)
);
CREATE TABLE IF NOT EXISTS course_audit (
    id INTEGER PRIMARY KEY AUTOINCREMENT, -- the order events were written in (a page's cursor)
    course_id TEXT NOT NULL,
    at REAL NOT NULL,                     -- Unix time (s), the API's clock
    who TEXT NOT NULL,                    -- instructor:<id>, ta:<id>, admin, student:<id>, lms
    action TEXT NOT NULL,                 -- publish, edit, regrade, extension, student.add, ... (audit.py)
    assignment_id TEXT,                   -- what it names, for the filters (NULL: not an assignment's)
    student TEXT,
    target TEXT NOT NULL,                 -- JSON: {course, assignment?, student?, submission?, staff?}
    before TEXT,                          -- JSON (NULL: nothing before, e.g. a student added)
    after TEXT,                           -- JSON (NULL: nothing after, e.g. a student removed)
    why TEXT NOT NULL DEFAULT ''
);
CREATE INDEX IF NOT EXISTS course_audit_course ON course_audit (course_id, id);
CREATE INDEX IF NOT EXISTS course_audit_student ON course_audit (course_id, student, id);
CREATE INDEX IF NOT EXISTS course_audit_assignment ON course_audit (assignment_id, id);
CREATE TABLE IF NOT EXISTS course_regrade_requests (
    id TEXT PRIMARY KEY,                  -- 32 hex digits
    assignment_id TEXT NOT NULL,
    submission_id TEXT NOT NULL,          -- course_submissions.id: the student's counting one when they asked
    student TEXT NOT NULL,
    item TEXT NOT NULL,                   -- a test's name (validity, a requirement, an image test) or a manual item's
    kind TEXT NOT NULL,                   -- test or manual
    reason TEXT NOT NULL,
    status TEXT NOT NULL,                 -- open, accepted or declined (server/course/regrade.py)
    reply TEXT NOT NULL DEFAULT '',       -- the latest answer's
    points REAL,                          -- the points the latest accepted answer set (NULL: none set)
    created_at REAL NOT NULL,
    answered_at REAL,
    answered_by TEXT                      -- the audit trail's name of who answered last
);
CREATE INDEX IF NOT EXISTS course_regrade_requests_assignment ON course_regrade_requests (assignment_id, status);
CREATE INDEX IF NOT EXISTS course_regrade_requests_submission ON course_regrade_requests (submission_id, item);
CREATE TABLE IF NOT EXISTS course_regrade_events (
    id INTEGER PRIMARY KEY AUTOINCREMENT, -- the order of a request's changes
    request_id TEXT NOT NULL,
    at REAL NOT NULL,
    who TEXT NOT NULL,
    kind TEXT NOT NULL,                   -- request or answer
    change TEXT NOT NULL                  -- JSON: status, reason or reply, points before and after
);
CREATE INDEX IF NOT EXISTS course_regrade_events_request ON course_regrade_events (request_id, id);
CREATE TABLE IF NOT EXISTS course_test_overrides (
    submission_id TEXT NOT NULL,          -- a test's points set by an accepted regrade request
    test TEXT NOT NULL,                   -- the test's policy name
    assignment_id TEXT NOT NULL,
    version INTEGER NOT NULL,             -- the version whose grading gave `original` (another: not applied)
    original REAL NOT NULL,               -- the points the grading gave
    points REAL NOT NULL,                 -- the points the answer set
    request_id TEXT NOT NULL,
    at REAL NOT NULL,
    PRIMARY KEY (submission_id, test)
);
CREATE INDEX IF NOT EXISTS course_test_overrides_assignment ON course_test_overrides (assignment_id);
"""


class CourseRow(TypedDict):
    """A row of `courses`, as CourseStore returns it."""

    id: str
    name: str
    created_at: float
    late_tokens: int


class StaffRow(TypedDict):
    """A row of `course_staff`: one of a course's instructors or TAs."""

    course_id: str
    person: str
    name: str
    email: str
    role: str  # a Role: instructor or ta
    lti_user: str | None
    gen: int
    created_at: float


class MemberRow(TypedDict):
    """A row of `course_members`: a student of a course's roster (RosterTables.members, .member)."""

    course_id: str
    student: str
    name: str
    email: str
    self_declared: int  # 0 or 1
    every: int  # 0 or 1
    lti_user: str | None
    gen: int
    created_at: float
    left_at: float | None


class StudentRow(TypedDict):
    """A student of an assignment's roster, as RosterTables.students, .student and .by_token return one: their
    enrolment (`course_enrolments`) joined with their member row (server/course/roster_store.py's STUDENT)."""

    assignment_id: str
    student: str
    name: str
    email: str
    self_declared: int
    deadline: float | None  # their extension (Unix time); None: the assignment's
    created_at: float  # when they were enrolled in it
    course_id: str
    lti_user: str | None
    left_at: float | None


class VersionRow(TypedDict):
    """A version of an assignment (`course_versions`), as CourseStore.versions returns it: its spec and policy
    parsed from their JSON, `id` the assignment's, `version_at` when the version was published."""

    id: str
    version: int
    spec: dict  # the grading spec (server/grading/), its reference scene inline
    policy: dict  # the Policy's fields (server/course/policy.py), as stored
    run_id: str
    version_at: float


class AssignmentRow(VersionRow):
    """An assignment (`course_assignments`) with its current version (CourseStore.assignment): what the course's
    mixins and views take as `a`."""

    created_at: float
    course_id: str


class SubmissionRow(TypedDict):
    """A row of `course_submissions`, as SubmissionTables.unhanded and .regrade return it (a submission before
    it is inserted is a plain dict: `handed` and `tokens_spent` are set by add_submission)."""

    id: str
    assignment_id: str
    student: str
    version: int
    run_id: str
    kind: str  # scene, png or exr
    file: str  # relative to DATA/course/
    accepted_at: float
    late: int  # 0 or 1 (the service's submissions() set it by the deadline as it is now)
    handed: int  # 0 or 1
    tokens_spent: int


class _Graded(SubmissionRow):
    stage: str | None
    status: str | None
    score: float | None
    max_score: float | None


class SubmissionWithGrade(_Graded, total=False):
    """A submission with its grading row's stage, status and exact score (None until graded), as
    SubmissionTables.submissions and .submission return it: the `sub` the course's mixins and views read.
    (`total=False` for `auto_score` alone: NotRequired is not seen at run time under postponed annotations.)"""

    auto_score: float  # the grading's own score, where accepted regrade requests moved `score`


class RegradeRequestRow(TypedDict):
    """A row of `course_regrade_requests`: a student's request on one item of a submission, as
    server/course/regrade_store.py's create, one and of_assignment return it (the `row` of the Regrade mixin)."""

    id: str
    assignment_id: str
    submission_id: str
    student: str
    item: str  # a test's policy name or a manual item's
    kind: str  # test or manual
    reason: str
    status: str  # open, accepted or declined
    reply: str
    points: float | None
    created_at: float
    answered_at: float | None
    answered_by: str | None


class _RegradeEvent(TypedDict):
    at: float
    who: str
    kind: str  # request or answer
    status: str


class RegradeEvent(_RegradeEvent, total=False):
    """A row of `course_regrade_events` as regrade_store.events returns it (a request's history): at, who and
    kind, its `change` (JSON) spread in: the status, and the reason and points of a request, the reply of an
    answer, with points_before and points when it moved them."""

    reason: str
    reply: str
    points: float | None
    points_before: float | None


class OverrideRow(TypedDict):
    """A row of `course_test_overrides` as regrade_store.overrides returns it, by submission and test: the version
    whose grading gave `original` (another version's grading: not applied) and the points the answer set."""

    version: int
    original: float
    points: float


class ManualGrade(TypedDict):
    """A grade of a staff-graded item as a grader gives it (ManualTables.set_manual's `row`; the mixin's
    manual_points scores one by the current spec)."""

    rubric: list[str]  # the chosen levels' names
    points: float | None  # the grader's override; None: the chosen levels' sum
    comment: str
    grader: str | None  # course_staff.person; None: the admin


class ManualGradeRow(ManualGrade):
    """A row of `course_manual_grades`, as ManualTables.manual_grades returns it (by submission and item), its
    rubric parsed from its JSON."""

    submission_id: str
    item: str
    assignment_id: str
    graded_at: float


class ManualRow(TypedDict):
    """A row of `course_manual`: an assignment's release and anonymity, as ManualTables.manual_state returns it
    (not released, not anonymous when it has no row yet)."""

    assignment_id: str
    released_at: float | None
    released_by: str | None
    anonymous: int  # 0 or 1


class TokenRow(TypedDict):
    """A row of `course_tokens`: whose a token is (CourseStore.token), its hash also the owner of its workspace
    jobs."""

    token_hash: str
    course_id: str
    kind: str  # a Kind: student or staff
    person: str  # course_members.student or course_staff.person
    created_at: float


class TokenGrantRow(TypedDict):
    """A row of `course_token_grants`: late tokens granted to a student (CourseStore.token_grants)."""

    course_id: str
    student: str
    added: int  # tokens (days) granted
    before: int  # the student's tokens left before, and after
    after: int
    who: str  # the staff member's id (or 'admin')
    why: str
    at: float


class ExtensionRow(TypedDict):
    """A row of `course_extensions`: a student's deadline moved on an assignment (RosterTables.extensions)."""

    assignment_id: str
    student: str
    before: float | None  # their own deadline before (None: the assignment's), and after
    after: float | None
    who: str  # the staff member's id (or 'admin')
    why: str
    at: float


class AuditEvent(TypedDict):
    """A row of `course_audit` as server/course/audit.py's events returns it (the trail's API and CSV): its id,
    when (ISO 8601), who, the action, the target, before and after (parsed from their JSON) and why; the
    course, assignment and student columns are the target's."""

    id: int
    at: str  # ISO 8601
    who: str  # instructor:<id>, ta:<id>, admin, student:<id>, lms
    action: str
    target: dict[str, str]  # audit.Target's json(): course, assignment?, student?, submission?, staff?
    before: Any  # JSON; None: nothing before
    after: Any  # JSON; None: nothing after
    why: str
